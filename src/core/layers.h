#pragma once
// The small layers every model is built from. Each loads its parameters by name from a WeightView (shape-checked
// at construction, so a whole model is validated before it runs) and forwards through the kernels.
#include <string>

#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

// y = x·Wᵀ + b, W stored [out, in] in its file dtype.
struct Linear {
  int64_t in = 0, out = 0;
  WeightRef weight;
  Tensor bias;  // empty when the layer has no bias
  Linear() = default;
  Linear(const WeightView& w, const std::string& name, int64_t in, int64_t out, bool has_bias = true);
  // x [rows, in] -> y [rows, out]; accumulate: y += result (fused residual add).
  void forward(const float* x, int64_t rows, float* y, Act act = Act::None, bool accumulate = false) const;
  // GEGLU of the projection: x [rows, in] -> y [rows, out / 2] = value half * GELU(gate half) (gemm_geglu; scratch
  // [rows, out] where geglu_needs_scratch()).
  void forward_geglu(const float* x, int64_t rows, float* y, float* scratch) const;
  bool geglu_needs_scratch() const { return gemm_geglu_needs_scratch(out / 2, in); }
};

struct Conv2d {
  Conv2dGeom geom;
  WeightRef weight;
  Tensor bias;
  Conv2d() = default;
  // weight [cout, cin, k, k], bias [cout]; padding and stride as given.
  Conv2d(const WeightView& w, const std::string& name, int64_t cin, int64_t cout, int64_t kernel, int64_t stride,
         int64_t pad, bool has_bias = true);
  // x [n, cin, h, w] -> y [n, cout, out_h, out_w]
  void forward(const float* x, int64_t n, int64_t h, int64_t w, float* y, Act act = Act::None,
               bool accumulate = false) const;
};

// Conv3d with kernel (3,1,1), padding (1,0,0), on frame-major activations [b*f, c, hw].
struct TemporalConv3 {
  int64_t cin = 0, cout = 0;
  WeightRef weight;
  Tensor bias;
  TemporalConv3() = default;
  TemporalConv3(const WeightView& w, const std::string& name, int64_t cin, int64_t cout);
  // y_stride: floats between output rows (0: hw), see conv_temporal3.
  void forward(const float* x, int64_t b, int64_t f, int64_t hw, float* y, Act act = Act::None,
               bool accumulate = false, int64_t y_stride = 0) const;
};

struct GroupNorm {
  int64_t c = 0, groups = 32;
  float eps = 1e-5f;
  Tensor gamma, beta;
  GroupNorm() = default;
  GroupNorm(const WeightView& w, const std::string& name, int64_t c, int64_t groups, float eps);
  // x [batch, frames, c, s]; statistics over frames (frames = 1: per-frame 4-D GroupNorm). y may alias x.
  void forward(const float* x, float* y, int64_t batch, int64_t frames, int64_t s, bool silu) const;
};

struct LayerNorm {
  int64_t c = 0;
  float eps = 1e-5f;
  Tensor gamma, beta;
  LayerNorm() = default;
  LayerNorm(const WeightView& w, const std::string& name, int64_t c, float eps);
  void forward(const float* x, float* y, int64_t rows) const;  // y may alias x
};

// Operand view of a stored weight for the kernels (W [out, in] as B transposed).
Operand weight_operand_t(const WeightRef& w, int64_t ld);

}  // namespace egopd
