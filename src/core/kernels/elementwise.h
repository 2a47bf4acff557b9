#pragma once
// Element-wise activations, GEGLU, nearest upsampling, sinusoidal embeddings. Float32.
#include <cstdint>

namespace egopd {

void silu_inplace(float* x, int64_t n);
void gelu_inplace(float* x, int64_t n);        // exact: 0.5 x (1 + erf(x / sqrt 2))
void quick_gelu_inplace(float* x, int64_t n);  // x * sigmoid(1.702 x)
void erf_inplace(float* x, int64_t n);         // erf, as used inside GELU (exposed for accuracy tests)

// GEGLU tail: p [rows, 2*d] (the projection output) -> out [rows, d] (row stride ldo, 0: d),
// out = p[:, :d] * GELU(p[:, d:]).
void geglu(const float* p, int64_t rows, int64_t d, float* out, int64_t ldo = 0);
// One row from separate halves: out[j] = a[j] * GELU(g[j]), j < d (not threaded: for callers inside a region).
void geglu_row(const float* a, const float* g, int64_t d, float* out);

// Nearest-neighbour 2x upsample: x [planes, h, w] -> y [planes, 2h, 2w], y[i,j] = x[i/2, j/2].
void upsample_nearest2x(const float* x, int64_t planes, int64_t h, int64_t w, float* y);

// diffusers get_timestep_embedding(flip_sin_to_cos=True, downscale_freq_shift=0, max_period=10000), float32 recipe:
// out[r] = [cos(t_r f_0..f_{half-1}), sin(...)], f_i = exp(float(-ln 10000) * i / half), for each of n values t.
// out is [n, dim]; dim must be even.
void timestep_embedding(const float* t, int64_t n, int64_t dim, float* out);

// y = a * x + (1 - a) * y   (AlphaBlender-style mix in place into y)
void blend_inplace(float* y, const float* x, float a, int64_t n);
void add_inplace(float* y, const float* x, int64_t n);
// y = x, n floats; threaded when large (an activation-sized memcpy on one thread keeps the other waiting).
void copy_floats(float* y, const float* x, int64_t n);

}  // namespace egopd
