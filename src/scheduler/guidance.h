#pragma once
// SVD's frame-wise linear classifier-free guidance (scheduler.md §2): scale g_f rises linearly over the frames
// from min to max; CFG is on exactly when max > 1, with the batch doubled as [uncond, cond].
#include <cstdint>
#include <vector>

#include "core/tensor.h"

namespace egopd {

inline bool guidance_enabled(float max_guidance_scale) { return max_guidance_scale > 1.0f; }

// torch.linspace(min, max, frames) in float32 (its scalar recipe: start + step*f for the first half,
// end - step*(frames-1-f) for the second; [min] when frames == 1).
std::vector<float> frame_guidance_scales(float min_scale, float max_scale, int64_t frames);

// v = v_u + g_f (v_c - v_u) per frame, float32. Inputs are [batch, frames, frame_elems] row-major; g has one
// scale per frame. out may alias either input.
void cfg_combine(const float* v_uncond, const float* v_cond, const std::vector<float>& g, int64_t batch,
                 int64_t frame_elems, float* out);
// Tensors [B, F, ...] (same shape); g.size() must equal F.
Tensor cfg_combine(const Tensor& v_uncond, const Tensor& v_cond, const std::vector<float>& g);

}  // namespace egopd
