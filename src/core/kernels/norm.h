#pragma once
// Normalisations (biased variance, float32 I/O, statistics accumulated in double or compensated float).
#include <cstdint>

namespace egopd {

// GroupNorm on frame-major activations viewed as [batch, frames, c, s] (s = H*W). Statistics per (batch, group)
// over `frames` x (c/groups) x s values: frames = 1 gives the per-frame 4-D GroupNorm ([N,C,H,W], batch = N);
// frames = F gives the video GroupNorm of a 5-D [B,C,F,H,W] tensor without re-layout. y may alias x.
// silu: apply SiLU after the affine transform (fused GroupNorm+SiLU).
void group_norm(const float* x, float* y, int64_t batch, int64_t frames, int64_t c, int64_t s, int64_t groups,
                const float* gamma, const float* beta, float eps, bool silu);

// LayerNorm over the last dimension of x [rows, c]; y may alias x. gamma/beta may be null (no affine).
void layer_norm(const float* x, float* y, int64_t rows, int64_t c, const float* gamma, const float* beta, float eps);

// In-place softmax over each row of x [rows, cols].
void softmax_rows(float* x, int64_t rows, int64_t cols);

}  // namespace egopd
