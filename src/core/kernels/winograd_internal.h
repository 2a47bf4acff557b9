#pragma once
// Private interface between the Winograd driver (winograd.cpp) and the per-path transform kernels
// (winograd_transforms.h, instantiated for each kernel path with that path's instruction set and lane count).
//
// Layouts, for one block of tiles and one block of output channels:
//   V[xi][panel][c][L]  transformed input: the GEMM's packed B panels (L = NR tiles wide), xi = k*alpha + l;
//   U[xi][o/MR][c][MR]  transformed filters: the GEMM's packed A panels;
//   M[xi][o][tile]      the products, row stride = tiles in the block.
#include <cstdint>

#include "core/cpu.h"
#include "core/kernels/gemm.h"

namespace egopd::wino_detail {

constexpr int kMaxLanes = 32;  // the widest NR (avx512)
constexpr int kMaxRows = 12;   // the tallest MR (avx512)

// Lanes [j0, j1) of a panel are the consecutive tiles tx0, tx0+1, ... of tile row ty of frame f.
struct Segment {
  int64_t f, ty, tx0;
  int j0, j1;
};

// Where the L tiles of a panel lie (lanes past the last segment are not tiles: their V columns are zero).
struct PanelGeom {
  int64_t h = 0, w = 0;  // frame size
  int nseg = 0;
  Segment seg[kMaxLanes];
};

// What the transforms do to their operands' values first, as the direct convolution does to the products' operands
// (gemm.h, Precision): nothing (Fp32), round them to bfloat16 (Bf16), or quantise them to int8 and back (Int8).
enum class OperandRounding : uint8_t { None, Bf16, Int8 };
constexpr int kRoundings = 3;

// Int8 input: value x of channel c at pixel p of frame f becomes clamp(nearbyint(x * inv), -127, 127) * scale,
// with inv and scale at [(f * groups + c / group) * h * w + p] (the pixel's largest magnitude over its group of
// channels, gemm.h's i8_inverse / i8_scale).
struct InputQuant {
  const float* inv = nullptr;
  const float* scale = nullptr;
  int64_t group = 1, groups = 1;
};

// Input transform of channels [c0, c1) of one panel: dst[xi*xi_stride + c*L + j] = (Bᵀ d B)[xi] of tile j.
// x is frame-major [n, cin, h, w]; q is read under OperandRounding::Int8 only.
using InputPanelFn = void (*)(const float* x, int64_t cin, const PanelGeom& pg, int64_t c0, int64_t c1, float* dst,
                              int64_t xi_stride, const InputQuant* q);

struct OutputEpilogue {
  float* y;         // frame-major [n, cout, h, w]
  int64_t cout, o;  // the output channel written
  float bias;
  Act act;
  bool accumulate;
};
// Output transform of one output channel of one panel: src[xi*xi_stride + j] is M[xi] of tile j.
using OutputPanelFn = void (*)(const float* src, int64_t xi_stride, const PanelGeom& pg, const OutputEpilogue& ep);

// Filter transform of R output channels (lanes) of `channels` (<= kMaxLanes) input channels c:
// g[(c*9 + t)*R + i] (tap t = ky*3 + kx) -> u[xi*xi_stride + c*R + i] = G g_c Gᵀ, R = the MR of the path's GEMM, so
// that u is a run of U's packed panels. The taps come rounded (RoundTapsBf16Fn, RoundTapsFn); g is read up to
// kFilterOverread floats past its channels * 9 * R taps.
using FilterFn = void (*)(const float* g, int channels, float* u, int64_t xi_stride);
constexpr int kFilterOverread = 8;

// n taps rounded to bfloat16 in place (OperandRounding::Bf16), on whole vectors.
using RoundTapsBf16Fn = void (*)(float* g, int64_t n);

// Int8 weights of R output channels (lanes): scale rows of `ld` floats, one per quantisation group of `group` taps,
// already offset to the first lane's output channel.
struct TapScales {
  const float* inv;
  const float* scale;
  int64_t group, ld;
};
// Taps [k0, k0 + nk) of the layer's cin * 9 (k = c * 9 + t), g[(k - k0)*R + i] for lane i, become
// clamp(nearbyint(g * inv), -127, 127) * scale with the inv and scale of their group, at [(k / group) * ld + i].
using RoundTapsFn = void (*)(float* g, int64_t k0, int64_t nk, const TapScales& s);

// One kernel path's transforms, indexed by [OperandRounding][tile], tile [0] F(2x2,3x3), [1] F(4x4,3x3).
struct WinogradKernels {
  int lanes = 16;  // L, the NR of the path's GEMM
  int rows = 6;    // R, the MR of the path's GEMM
  InputPanelFn input[kRoundings][2] = {};
  OutputPanelFn output[2] = {};
  FilterFn filter[2] = {};  // float32 (the taps come rounded)
  RoundTapsBf16Fn round_taps_bf16 = nullptr;
  RoundTapsFn round_taps_i8 = nullptr;
};
const WinogradKernels& winograd_kernels(KernelPath p);

const WinogradKernels& winograd_kernels_portable();
const WinogradKernels& winograd_kernels_avx2();
const WinogradKernels& winograd_kernels_avx512();
const WinogradKernels& winograd_kernels_neon();

// Scratch budgets of conv2d_winograd (bytes), which choose its blocking; tests shrink them to reach every blocking
// on small shapes.
struct WinogradBudgets {
  int64_t filter = int64_t(16) << 20;       // U: one block of output channels ...
  int64_t filter_near = 0;                   // ... or at most this (0: 4x L2) where V's slice fits in L2
  int64_t whole_filter = int64_t(48) << 20;  // ... or all of them, rather than transforming V again per block
  int64_t tiles = int64_t(4) << 20;         // V + M: one block of tiles ...
  int64_t whole_tiles = int64_t(32) << 20;  // ... or all tiles, when several blocks of output channels share them
  int64_t min_block_tiles = 128;            // U is re-read for every block of tiles: >= 64 flops per byte of it
};
WinogradBudgets& winograd_budgets();

// How conv2d_winograd blocks a call of ntiles tiles (a2 = alpha^2 tile positions, mr x lanes micro-tiles) on
// `threads` threads.
struct WinogradBlocking {
  int64_t co = 0, ncb = 0;   // output channels per block (a multiple of mr), blocks
  int64_t tb = 0, ntb = 0;   // tiles per block (a multiple of lanes), blocks
  bool tiles_outside = false;  // loop over tile blocks outside (U recomputed per tile block), else V per channel block
  bool own_rows = false;       // thread t keeps to rows [t, t + 1) * co / threads of every block (co a multiple of
                               // threads x mr) in the filter transforms, the products and the output transforms
};
WinogradBlocking winograd_blocking(int64_t cin, int64_t cout, int64_t ntiles, int64_t a2, int mr, int lanes,
                                   int threads);

// act applied in place to n values (the element-wise kernels; serial for the small blocks passed here).
void apply_act_inplace(Act act, float* v, int64_t n);

}  // namespace egopd::wino_detail
