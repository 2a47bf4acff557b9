#include "scheduler/guidance.h"

#include "core/error.h"

namespace egopd {

std::vector<float> frame_guidance_scales(float min_scale, float max_scale, int64_t frames) {
  if (frames < 1) throw Error("guidance: number of frames must be >= 1, got " + std::to_string(frames));
  std::vector<float> g(frames, min_scale);
  if (frames == 1) return g;
  const float step = (max_scale - min_scale) / float(frames - 1);
  const int64_t halfway = frames / 2;
  for (int64_t f = 0; f < frames; ++f)
    g[f] = f < halfway ? min_scale + step * float(f) : max_scale - step * float(frames - 1 - f);
  return g;
}

void cfg_combine(const float* v_uncond, const float* v_cond, const std::vector<float>& g, int64_t batch,
                 int64_t frame_elems, float* out) {
  const int64_t frames = int64_t(g.size());
  for (int64_t b = 0; b < batch; ++b)
    for (int64_t f = 0; f < frames; ++f) {
      const int64_t base = (b * frames + f) * frame_elems;
      const float gf = g[f];
      for (int64_t k = base; k < base + frame_elems; ++k) {
        const float u = v_uncond[k];
        out[k] = u + gf * (v_cond[k] - u);
      }
    }
}

Tensor cfg_combine(const Tensor& v_uncond, const Tensor& v_cond, const std::vector<float>& g) {
  if (v_uncond.shape() != v_cond.shape())
    throw Error("guidance: uncond output " + v_uncond.shape().str() + " and cond output " + v_cond.shape().str() +
                " differ in shape");
  if (v_uncond.ndim() < 2 || v_uncond.dim(1) != int64_t(g.size()))
    throw Error("guidance: output " + v_uncond.shape().str() + " is not [B, F, ...] with F = " +
                std::to_string(g.size()));
  Tensor out(v_uncond.shape());
  if (out.numel() == 0) return out;
  const int64_t batch = v_uncond.dim(0);
  const int64_t frame_elems = v_uncond.numel() / (batch * int64_t(g.size()));
  cfg_combine(v_uncond.data(), v_cond.data(), g, batch, frame_elems, out.data());
  return out;
}

}  // namespace egopd
