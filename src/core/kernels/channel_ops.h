#pragma once
// Per-channel operations on frame-major NCHW activations [n, c, s] (s = H*W).
#include <cstdint>

namespace egopd {

// x[i, j, :] += bias[i*c + j]   (a per-(frame, channel) bias, e.g. a time-embedding projection) ; bias [n, c]
void add_frame_channel_bias(float* x, int64_t n, int64_t c, int64_t s, const float* bias);

// [n, c1, s] ++ [n, c2, s] -> [n, c1+c2, s]   (skip concatenation, first operand first)
void concat_channels(const float* a, int64_t c1, const float* b, int64_t c2, int64_t n, int64_t s, float* out);

// x[r, :] += v[r / rows_per_vec, :] for r in [0, rows): broadcast-add one c-vector per group of rows; x [rows, c]
void add_row_vectors(float* x, int64_t rows, int64_t c, const float* v, int64_t rows_per_vec);

}  // namespace egopd
