#pragma once
// Re-layouts between NCHW frames and token matrices (unet3d.md §2).
#include <cstdint>

namespace egopd {

// Batched transpose: for each of `batch` matrices, src [rows, cols] -> dst [cols, rows].
// Tok:  [N, C, L] -> [N, L, C]  is transpose(batch=N, rows=C, cols=L).
// Tok⁻¹ is transpose(batch=N, rows=L, cols=C).
void transpose_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols);

// dst += transpose(src) per matrix: src [batch, rows, cols], dst [batch, cols, rows] (Tok⁻¹ plus a residual).
void transpose_add_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols);

// Seq:  [B*F, L, C] -> [B*L, F, C]  (s[b*L+l, f, :] = t[b*F+f, l, :]); Seq⁻¹ swaps f and l back.
void frames_to_sequences(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c);
void sequences_to_frames(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c);

}  // namespace egopd
