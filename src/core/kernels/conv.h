#pragma once
// Convolutions on frame-major NCHW activations. Zero padding, cross-correlation, float32 arithmetic; weights in
// their stored dtype (F32/F16/BF16/I8+scale), converted while packing. Same epilogue as gemm (bias per output
// channel, fused activation, fused residual accumulate). Fast paths for 1x1 and 3x3 that never materialise the
// im2col of a whole input; any kernel/stride/padding works (patch embedding: kernel = stride = 14).
#include <cstdint>
#include <string>

#include "core/kernels/gemm.h"

namespace egopd {

// How conv2d computes 3x3 stride-1 pad-1 convolutions (all other geometries are always direct): the implicit-GEMM
// direct convolution, Winograd (winograd.h; F(4x4,3x3), or F(2x2,3x3) on frames smaller than 8), or Auto:
// Winograd where winograd_wins() says it is faster, else direct. Process-wide; default Auto, or EGOPD_CONV=
// direct|winograd|auto (read on first use; an unknown value is an error).
enum class ConvAlgo : uint8_t { Direct, Winograd, Auto };
const char* conv_algo_name(ConvAlgo a);                        // "direct", "winograd", "auto"
bool conv_algo_from_name(const std::string& s, ConvAlgo* out);  // false for anything else
ConvAlgo conv_algo();
// The default: EGOPD_CONV when set (an Error naming it when it is not direct, winograd or auto), else Auto.
ConvAlgo conv_algo_from_env();
// Not thread-safe: call it between kernel calls, never during one (like set_kernel_path).
void set_conv_algo(ConvAlgo a);

struct Conv2dGeom {
  int64_t cin = 0, cout = 0;
  int64_t kh = 1, kw = 1;
  int64_t stride_h = 1, stride_w = 1;
  int64_t pad_h = 0, pad_w = 0;
  int64_t out_h(int64_t h) const { return (h + 2 * pad_h - kh) / stride_h + 1; }
  int64_t out_w(int64_t w) const { return (w + 2 * pad_w - kw) / stride_w + 1; }
};

// x [n, cin, h, w] -> y [n, cout, out_h, out_w]; weight [cout, cin, kh, kw]; bias [cout] or null.
// ep.bias is ignored (pass bias here); ep.bias_per_row is implied.
void conv2d(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
            const Conv2dGeom& g, float* y, Act act = Act::None, bool accumulate = false);

// What conv2d runs for this call under the current settings: "direct" or "winograd F(4x4,3x3)" / "... F(2x2,3x3)".
std::string conv2d_algorithm(const Conv2dGeom& g, int64_t n, int64_t h, int64_t w);

// Temporal convolution, kernel (3,1,1), padding (1,0,0) with zeros in time, on frame-major activations:
// x [b*f, cin, hw] -> y [b*f, cout, hw], y[b,t,o] = bias[o] + sum_{c,k} W[o,c,k] x[b,t+k-1,c].
// weight is the stored [cout, cin, 3, 1, 1] tensor. Under ConvAlgo Winograd, or Auto on 32+ pixels per frame and
// 16+ channels, with two frames or more: Winograd F(2,3) or F(4,3) along time (conv_temporal.cpp; bf16 and int8:
// F(2,3) on rounded or quantised transforms, int8 under Auto only where GemmPath::i8_temporal_winograd).
// y_stride: floats between consecutive output rows (0: hw), e.g. to write a tile of pixels into a whole video.
void conv_temporal3(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                    const float* bias, int64_t cout, float* y, Act act = Act::None, bool accumulate = false,
                    int64_t y_stride = 0);

// What conv_temporal3 runs for this call under the current settings: "direct", "winograd F(2,3)" or "winograd F(4,3)".
std::string conv_temporal3_algorithm(int64_t f, int64_t cin, int64_t cout, int64_t hw);

}  // namespace egopd
