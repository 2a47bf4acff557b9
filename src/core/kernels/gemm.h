#pragma once
// SGEMM: C[M,N] (+)= act(op(A)[M,K] · op(B)[K,N] + bias). Packed panels, cache blocking, OpenMP inside
// (never call it from inside a parallel region of your own), AVX2/FMA micro-kernel with a portable path beside it.
// Operands may be stored as F32, F16 or BF16 (converted to float32 while packing; F16 via F16C), or as I8 with one
// float scale per output channel (dequantised while packing). All arithmetic is float32.
#include <cstdint>

#include "core/dtype.h"

namespace egopd {

enum class Act : uint8_t { None, SiLU, GELU, QuickGELU };  // GELU = exact erf form

// Logical matrix [rows, cols]: element (r, c) is at data[r*ld + c] when !trans, at data[c*ld + r] when trans.
// Linear layers pass the weight W [out, in] as B with trans = true (y = x·Wᵀ).
struct Operand {
  const void* data = nullptr;
  DType dtype = DType::F32;
  int64_t ld = 0;
  bool trans = false;
  const float* scale = nullptr;  // I8 only: one scale per output channel (per column of B, per row of A)
  // The address of stored element i (counted from data, in elements of dtype).
  const void* element(int64_t i) const { return static_cast<const char*>(data) + i * int64_t(dtype_size(dtype)); }
};

inline Operand f32_operand(const float* p, int64_t ld, bool trans = false) { return {p, DType::F32, ld, trans, nullptr}; }

struct Epilogue {
  const float* bias = nullptr;  // bias[n] per column (linear), or bias[m] per row when bias_per_row (conv, NCHW)
  bool bias_per_row = false;
  Act act = Act::None;          // applied to (A·B + bias)
  bool accumulate = false;      // C = C + act(A·B + bias)   (fused residual add)
};

void gemm(int64_t M, int64_t N, int64_t K, const Operand& A, const Operand& B, float* C, int64_t ldc,
          const Epilogue& ep = {});

// GEGLU of a linear layer: out[M, D] = (x·Wvᵀ + bv) * GELU(x·Wgᵀ + bg), with W = B (trans, [2D, K]: the value rows
// Wv first, then the gate rows Wg) and bias [2D] (or null) split the same way; out has row stride ldo. The same
// numbers as gemm into a [M, 2D] temporary followed by geglu (elementwise.h), without that temporary where it can:
// each tile of value columns is multiplied beside its tile of gate columns and combined while in cache. Where the
// kernel path's panels do not divide D, or K takes several passes, the projection goes through `scratch` ([M, 2D]
// floats; gemm_geglu_needs_scratch says when, and it may be null otherwise).
bool gemm_geglu_needs_scratch(int64_t D, int64_t K);
void gemm_geglu(int64_t M, int64_t D, int64_t K, const Operand& A, const Operand& B, const float* bias, float* out,
                int64_t ldo, float* scratch);

// Arithmetic of the GEMM engine (linear layers and convolutions), process-wide like the kernel path:
//   Fp32 (default): float32 operands, products and sums.
//   Bf16: both operands rounded to bfloat16 (nearest even) as they are packed, float32 accumulation. On CPUs with
//         AVX512-BF16 `vdpbf16ps` multiplies them (two products per lane and instruction); elsewhere the float32
//         micro-kernel multiplies the rounded values: the same exact products, only slower than Fp32.
//   Int8: both operands quantised symmetrically to int8 as they are packed, with one dynamic scale per row of A and
//         per column of B (per token and per output channel of a linear layer; per output channel and per pixel of
//         a convolution) in each block of at most kInt8Block of K: s = max|x| / 127, q = nearbyint(x * (127 / max))
//         (float32 arithmetic; a lane whose max is below 1e-30 quantises to zeros). The int8 products are summed
//         exactly in int32 and each block adds fma(float(sum), s_row * s_col, .) to the float32 result. q8 weights are
//         dequantised and requantised per block (exact where the block holds the channel's largest value).
//         Native kernels: `vpdpbusd` on AVX512-VNNI, `sdot` on NEON with the ARMv8.2 dot product, `vpmaddubsw` on
//         AVX2; elsewhere (portable, NEON without it, AVX-512 without VNNI) an exact scalar emulation (the same
//         numbers as vpdpbusd and sdot, slower than Fp32). The AVX2 path
//         quantises B to 63 levels instead (s = max|x| / 63, q within -63..63; int8_b_levels()): its unsigned x
//         signed byte products are summed in pairs in int16, which 127 levels would overflow. B is a linear
//         layer's weight and a convolution's input pixels; its error on that path is about twice as large.
//         3x3 convolutions that run Winograd under Int8 (winograd.h: forced, or --conv auto on the AVX2 path) quantise
//         with the same rule but per input pixel, and multiply in float32. Temporal convolutions that run Winograd
//         F(2,3) under Int8 (conv.h: forced, or --conv auto on the AVX2 path) quantise their transformed filters (A,
//         per output channel) and transformed frames (B, per pixel) by this rule. A NaN in a row of A or column of B
//         makes its scale NaN, so its outputs are NaN as in float32 (an inf makes them non-finite).
// Norms, activations and the softmax stay float32 in every mode; attention's two products follow Bf16 (attention.h)
// and stay float32 under Int8.
enum class Precision : uint8_t { Fp32, Bf16, Int8 };
constexpr int64_t kInt8Block = 512;                          // K block of one int8 scale (int32 sums stay exact)
// The balanced quantisation group of a K of `k` (k > 0): ceil(k / ceil(k / kInt8Block)), group g covering
// [g * group, (g + 1) * group).
inline int64_t int8_group(int64_t k) {
  const int64_t groups = (k + kInt8Block - 1) / kInt8Block;
  return (k + groups - 1) / groups;
}
const char* precision_name(Precision p);                     // "fp32", "bf16", "int8"
bool parse_precision(const char* name, Precision* out);      // false for an unknown name
Precision precision();
// Use precision p from now on. Not thread-safe: call it between kernel calls, never during one.
void set_precision(Precision p);
// Where Bf16 runs natively (vdpbf16ps) on the kernel path in use, or emulated.
bool bf16_native();
// How Int8 runs on the kernel path in use: "vpdpbusd (AVX512-VNNI)", "vpmaddubsw (AVX2, B in 63 levels)",
// "sdot (ARMv8.2 dot product)" or "emulated".
const char* int8_kernel();
// Largest quantised magnitude of Int8's B operand on the kernel path in use: 127, or 63 on AVX2.
int int8_b_levels();

// Scalar reference of the epilogue activations (shared by kernels and tests).
float apply_act(Act act, float x);

}  // namespace egopd
