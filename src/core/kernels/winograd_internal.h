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

// Input transform of channels [c0, c1) of one panel: dst[xi*xi_stride + c*L + j] = (Bᵀ d B)[xi] of tile j.
// x is frame-major [n, cin, h, w].
using InputPanelFn = void (*)(const float* x, int64_t cin, const PanelGeom& pg, int64_t c0, int64_t c1, float* dst,
                              int64_t xi_stride);

struct OutputEpilogue {
  float* y;         // frame-major [n, cout, h, w]
  int64_t cout, o;  // the output channel written
  float bias;
  Act act;
  bool accumulate;
};
// Output transform of one output channel of one panel: src[xi*xi_stride + j] is M[xi] of tile j.
using OutputPanelFn = void (*)(const float* src, int64_t xi_stride, const PanelGeom& pg, const OutputEpilogue& ep);

// Filter transform of L (output, input) channel pairs: g[t*L + j] (tap t = ky*3 + kx) -> u[xi*L + j] = G g Gᵀ.
using FilterFn = void (*)(const float* g, float* u);

// One kernel path's transforms, indexed by tile: [0] F(2x2,3x3), [1] F(4x4,3x3).
struct WinogradKernels {
  int lanes = 16;  // L, the NR of the path's GEMM
  InputPanelFn input[2] = {};
  OutputPanelFn output[2] = {};
  FilterFn filter[2] = {};
};
const WinogradKernels& winograd_kernels(KernelPath p);

const WinogradKernels& winograd_kernels_portable();
const WinogradKernels& winograd_kernels_avx2();
const WinogradKernels& winograd_kernels_avx512();
const WinogradKernels& winograd_kernels_neon();

// act applied in place to n values (the element-wise kernels; serial for the small blocks passed here).
void apply_act_inplace(Act act, float* v, int64_t n);

}  // namespace egopd::wino_detail
