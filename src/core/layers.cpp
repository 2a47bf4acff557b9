#include "core/layers.h"

#include "core/error.h"
#include "core/kernels/norm.h"

namespace egopd {

Operand weight_operand_t(const WeightRef& w, int64_t ld) { return Operand{w.data, w.dtype, ld, true, w.scale}; }

Linear::Linear(const WeightView& w, const std::string& name, int64_t in_, int64_t out_, bool has_bias)
    : in(in_), out(out_) {
  weight = w.get(name + ".weight", {out, in});
  if (has_bias) bias = w.get_f32(name + ".bias", {out});
}

void Linear::forward(const float* x, int64_t rows, float* y, Act act, bool accumulate) const {
  Epilogue ep;
  ep.bias = bias.empty() ? nullptr : bias.data();
  ep.act = act;
  ep.accumulate = accumulate;
  gemm(rows, out, in, f32_operand(x, in), weight_operand_t(weight, in), y, out, ep);
}

void Linear::forward_geglu(const float* x, int64_t rows, float* y, float* scratch) const {
  gemm_geglu(rows, out / 2, in, f32_operand(x, in), weight_operand_t(weight, in), bias.empty() ? nullptr : bias.data(),
             y, out / 2, scratch);
}

Conv2d::Conv2d(const WeightView& w, const std::string& name, int64_t cin, int64_t cout, int64_t kernel,
               int64_t stride, int64_t pad, bool has_bias) {
  geom = Conv2dGeom{cin, cout, kernel, kernel, stride, stride, pad, pad};
  weight = w.get(name + ".weight", {cout, cin, kernel, kernel});
  if (has_bias) bias = w.get_f32(name + ".bias", {cout});
}

void Conv2d::forward(const float* x, int64_t n, int64_t h, int64_t w, float* y, Act act, bool accumulate) const {
  Operand op{weight.data, weight.dtype, geom.cin * geom.kh * geom.kw, false, weight.scale};
  conv2d(x, n, h, w, op, bias.empty() ? nullptr : bias.data(), geom, y, act, accumulate);
}

TemporalConv3::TemporalConv3(const WeightView& w, const std::string& name, int64_t cin_, int64_t cout_)
    : cin(cin_), cout(cout_) {
  weight = w.get(name + ".weight", {cout, cin, 3, 1, 1});
  bias = w.get_f32(name + ".bias", {cout});
}

void TemporalConv3::forward(const float* x, int64_t b, int64_t f, int64_t hw, float* y, Act act, bool accumulate,
                            int64_t y_stride) const {
  Operand op{weight.data, weight.dtype, cin * 3, false, weight.scale};
  conv_temporal3(x, b, f, cin, hw, op, bias.data(), cout, y, act, accumulate, y_stride);
}

GroupNorm::GroupNorm(const WeightView& w, const std::string& name, int64_t c_, int64_t groups_, float eps_)
    : c(c_), groups(groups_), eps(eps_) {
  if (c % groups != 0)
    throw Error(w.map().label() + ": " + w.key(name) + ": " + std::to_string(c) + " channels are not divisible into " +
                std::to_string(groups) + " groups");
  gamma = w.get_f32(name + ".weight", {c});
  beta = w.get_f32(name + ".bias", {c});
}

void GroupNorm::forward(const float* x, float* y, int64_t batch, int64_t frames, int64_t s, bool silu) const {
  group_norm(x, y, batch, frames, c, s, groups, gamma.data(), beta.data(), eps, silu);
}

LayerNorm::LayerNorm(const WeightView& w, const std::string& name, int64_t c_, float eps_) : c(c_), eps(eps_) {
  gamma = w.get_f32(name + ".weight", {c});
  beta = w.get_f32(name + ".bias", {c});
}

void LayerNorm::forward(const float* x, float* y, int64_t rows) const {
  layer_norm(x, y, rows, c, gamma.data(), beta.data(), eps);
}

}  // namespace egopd
