#pragma once
// Winograd convolutions F(m x m, 3x3), m = 2 or 4, for 3x3 stride-1 pad-1 convolutions on frame-major NCHW
// activations: y = Aᵀ[(G g Gᵀ) ⊙ (Bᵀ d B)]A per output tile, with the (m+2)^2 tile positions as batched GEMMs on
// the SGEMM engine's micro-kernels. Float32 arithmetic; weights in their stored dtype (F32/F16/BF16, or I8
// dequantised with its per-output-channel scale inside the filter transform). Under Precision::Bf16 the input values
// and weights are rounded to bfloat16 before their transforms. Under Precision::Int8 they are quantised to int8 and
// back before their transforms, with gemm.h's rule (s = max|v| / 127, q = nearbyint(v * (127 / max)) within
// -127..127, value q * s): the weights per output channel and int8_group of its cin * 9 taps, exactly as the direct
// convolution quantises them; the input per pixel and int8_group of its cin channels (the direct convolution's B
// scales cover a pixel's 3x3 neighbourhood instead, which a transform of whole tiles cannot follow), always in 127
// levels. conv2d() dispatches here according to conv_algo() (conv.h).
#include <cstdint>

#include "core/kernels/gemm.h"

namespace egopd {

enum class WinogradTile : uint8_t { F2x2, F4x4 };

const char* winograd_tile_name(WinogradTile t);  // "F(2x2,3x3)", "F(4x4,3x3)"

// The tile Winograd uses for a layer when it runs at all: F(4x4) unless the frame is too small for 4x4 tiles to
// pay (then F(2x2)).
WinogradTile winograd_tile_for(int64_t h, int64_t w);
// The auto choice: whether Winograd beats the direct convolution on this layer of n frames (3x3, stride 1, pad 1
// assumed).
bool winograd_wins(int64_t cin, int64_t cout, int64_t n, int64_t h, int64_t w);

// x [n, cin, h, w] -> y [n, cout, h, w]; weight [cout, cin, 3, 3] row-major (ld ignored); bias [cout] or null.
// Epilogue as conv2d: y = act(conv + bias), or y += act(conv + bias) when accumulate.
void conv2d_winograd(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                     int64_t cin, int64_t cout, float* y, Act act, bool accumulate, WinogradTile tile);

}  // namespace egopd
