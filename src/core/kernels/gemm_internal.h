#pragma once
// Private interface of the SGEMM engine shared by gemm*.cpp and conv*.cpp: block sizes, panel sources, the
// blocked driver and the micro-kernels. Not part of the public kernel API.
//
// Layout conventions (Goto/BLIS):
//   packed A micro-panel: kc x MR floats, element (i, k) at a[k*MR + i] (rows >= mr zero);
//   packed B micro-panel: kc x NR floats, element (k, j) at b[k*NR + j] (columns >= nr zero);
//   C tile: MR x NR, row-major with row stride ldc.
#include <cstdint>

#include "core/kernels/gemm.h"

namespace egopd::gemm_detail {

constexpr int MR = 6;   // micro-tile rows (6 x 16 = 12 ymm accumulators)
constexpr int NR = 16;  // micro-tile columns

// What the micro-kernel does with its MR x NR sum S when storing it to C:
//   C = act(S + (load_c ? C : 0) + bias) + (add_after ? C : 0), then only the mr x nr valid part is stored.
struct TileEpilogue {
  const float* bias_row = nullptr;  // bias of the tile's first row (bias_row[i]), or null
  const float* bias_col = nullptr;  // bias of the tile's first column (bias_col[j]), or null
  Act act = Act::None;
  bool load_c = false;
  bool add_after = false;
};

// A is read as a[i*a_rs + k*a_cs]: a packed micro-panel (a_rs = 1, a_cs = MR), or F32 row-major A in place
// (a_rs = lda, a_cs = 1). Rows >= mr are never read.
using MicroKernel = void (*)(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep);

void microkernel_portable(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                          int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void microkernel_avx2(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep);

// Scalar epilogue of one tile from an MR x NR sum (row stride NR); shared by both paths for partial tiles.
void store_tile_scalar(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep);

// Source of the A operand [M, K]: in place (F32 row-major) or packed MR rows at a time.
struct ASource {
  const float* direct = nullptr;  // non-null: F32 row-major with row stride lda, read in place
  int64_t lda = 0;
  virtual ~ASource() = default;
  // dst[k*MR + i] = A(m0 + i, k0 + k) for i < mr, 0 for mr <= i < MR.
  virtual void pack(int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const {}
};

// Source of the B operand: `segments` independent column ranges of width seg_cols that share A (frames of a
// convolution); the output of segment s starts at C + s * c_seg_stride.
struct BSource {
  virtual ~BSource() = default;
  // dst[k*NR + j] = B_seg(k0 + k, n0 + j) for j < nr, 0 for nr <= j < NR.
  virtual void pack(int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, float* dst) const = 0;
};

struct GemmJob {
  int64_t M = 0, K = 0;
  int64_t segments = 1, seg_cols = 0;
  const ASource* a = nullptr;
  const BSource* b = nullptr;
  float* c = nullptr;
  int64_t ldc = 0, c_seg_stride = 0;
  Epilogue ep;  // bias per column (linear) or per row (conv)
};

// The blocked, threaded driver (threads = num_threads(), 1 inside a parallel region or for tiny jobs).
void run_gemm(const GemmJob& job);

// Operand-backed sources (any dtype, transposed or not), used by gemm() and the 1x1 convolution.
struct OperandA : ASource {
  Operand op;
  explicit OperandA(const Operand& o);
  void pack(int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const override;
};
struct OperandB : BSource {
  Operand op;
  int64_t seg_stride = 0;  // elements between segments (0 for a single matrix)
  explicit OperandB(const Operand& o, int64_t seg_stride_elems = 0) : op(o), seg_stride(seg_stride_elems) {}
  void pack(int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, float* dst) const override;
};

// Packing primitives. `p` points at element (k0, n0) / (m0, k0) of the operand, already offset.
// Portable: any dtype; I8 multiplies by scale (already offset to the first output channel).
void pack_b_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                     float* dst);
void pack_a_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                     float* dst);
// AVX2/F16C versions (same contract; partial panels and K tails go to the portable ones).
void pack_b_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                 float* dst);
void pack_a_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                 float* dst);

}  // namespace egopd::gemm_detail
