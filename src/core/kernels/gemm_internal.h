#pragma once
// Private interface of the SGEMM engine shared by gemm*.cpp and conv*.cpp: block sizes, panel sources, the
// blocked driver and the micro-kernels. Not part of the public kernel API.
//
// Layout conventions (Goto/BLIS):
//   packed A micro-panel: kc x MR floats, element (i, k) at a[k*MR + i] (rows >= mr zero);
//   packed B micro-panel: kc x NR floats, element (k, j) at b[k*NR + j] (columns >= nr zero);
//   C tile: MR x NR, row-major with row stride ldc.
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/cpu.h"
#include "core/kernels/gemm.h"

namespace egopd::conv_detail {
struct ShiftGeom;
}

namespace egopd::gemm_detail {

// Flops of a kernel call below which it runs on the calling thread (a parallel region costs more than it saves).
constexpr double kSerialFlops = 4e5;

// Micro-tile rows (MR) and columns (NR) of each path; packed panels are MR rows of A / NR columns of B wide.
constexpr int kMrPortable = 6, kNrPortable = 16;
constexpr int kMrAvx2 = 6, kNrAvx2 = 16;     // 12 ymm accumulators
constexpr int kMrAvx512 = 12, kNrAvx512 = 32;  // 24 zmm accumulators: 2 B loads and 12 broadcasts per 24 FMAs
constexpr int kMrNeon = 8, kNrNeon = 12;       // 24 q-register accumulators: 2 A + 3 B loads per 24 FMLAs
constexpr int kMaxMR = 12, kMaxNR = 32;
constexpr int kMaxTile = kMaxMR * kMaxNR;  // floats of the largest micro-tile of any path

// What the micro-kernel does with its MR x NR sum S when storing it to C:
//   C = act(S + (load_c ? C : 0) + bias) + (add_after ? C : 0), then only the mr x nr valid part is stored.
struct TileEpilogue {
  const float* bias_row = nullptr;  // bias of the tile's first row (bias_row[i]), or null
  const float* bias_col = nullptr;  // bias of the tile's first column (bias_col[j]), or null
  Act act = Act::None;
  bool load_c = false;
  bool add_after = false;
  int64_t i8_group = 0;  // Precision::Int8: rows of one quantisation group of the panels (see I8Group)
};

// A is read as a[i*a_rs + k*a_cs]: a packed micro-panel (a_rs = 1, a_cs = MR), or F32 row-major A in place
// (a_rs = lda, a_cs = 1). Rows >= mr are never read.
using MicroKernel = void (*)(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep);
// Packing of A: dst[k*MR + i] = A(i, k) (* scale[i]) for i < mr, 0 for mr <= i < MR (MR of the path).
// `p` points at element (m0, k0) of the operand, A(i, k) = p[i*ld + k], or p[k*ld + i] when trans.
using PackA = void (*)(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                       float* dst);
// Packing of B: dst[k*NR + j] = B(k, j) (* scale[j]) for j < nr, 0 for nr <= j < NR (NR of the path).
// B(k, j) = p[k*ld + j], or p[j*ld + k] when trans.
using PackB = void (*)(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                       float* dst);

// One kernel path of the GEMM engine: its micro-kernel and packers, and the blocking derived from the CPU's
// caches (gemm_paths.cpp). The convolution packers of the same path are in conv_internal.h.
struct GemmPath {
  int mr = 6;                  // micro-tile rows (A panels are packed mr rows at a time)
  int nr = 16;                 // micro-tile columns (B panels are packed nr columns at a time)
  MicroKernel micro = nullptr;
  bool a_in_place = false;     // the micro-kernel reads F32 row-major A in place (a_rs = lda, a_cs = 1)
  PackA pack_a = nullptr;
  PackB pack_b = nullptr;
  // Convolution packers (conv_internal.h): implicit im2col of a stride-1 frame, and the A panels of a temporal
  // convolution's weight for one tap (null: the generic scalar packing).
  void (*pack_im2col_shift)(const float* xf, const conv_detail::ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0,
                            int nr, float* dst) = nullptr;
  int64_t (*pack_a_temporal)(const void* w, DType dt, int64_t cin, int64_t m0, int64_t tap, int64_t c0,
                             int64_t len, float* dst) = nullptr;
  // The temporal Winograd's transformed frames (temporal_wino_pack.h): the m + 2 panels V_i = (Bᵀd)_i of F(m,3),
  // m = 2 or 4, from m + 2 float32 frames in[t] (rows at stride ld[t]), panel i at dst + i * panel_floats.
  void (*pack_b_temporal_wino)(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                               int64_t panel_floats) = nullptr;
  // Its output transform of one micro-tile (temporal_wino_pack.h: temporal_wino_out).
  void (*temporal_wino_output)(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                               const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                               int64_t row_stride) = nullptr;
  // Float32 3x3 stride-1 pad-1 convolution from a per-tile input window (conv_internal.h; null, or false returned:
  // the implicit GEMM above).
  bool (*conv3x3_window)(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                         int64_t cin, int64_t cout, float* y, Act act, bool accumulate) = nullptr;
  // Precision::Bf16 with a native bfloat16 dot product (null: emulated, the float32 panels are rounded in place).
  // to_bf16_pairs rewrites a packed float32 panel of `width` (MR or NR) columns and kc rows in place as ceil(kc/2)
  // rows of 32-bit pairs: slot p*width + i holds bf16(x(2p, i)) in its low and bf16(x(2p+1, i)) in its high half
  // (x(kc, i) = 0 for odd kc). micro_bf16 multiplies such A and B panels (kc is still the float32 depth).
  void (*to_bf16_pairs)(float* panel, int width, int64_t kc) = nullptr;
  MicroKernel micro_bf16 = nullptr;
  // pack_a / pack_b followed by to_bf16_pairs, in one pass (set with micro_bf16).
  PackA pack_a_bf16 = nullptr;
  PackB pack_b_bf16 = nullptr;
  // Precision::Int8: quantise a packed float32 panel `src` of `width` (MR or NR) lanes and kc rows into `dst`
  // (src itself, in place, or a buffer apart), `group` rows at a time (see I8Group), A's and B's in the format
  // micro_i8 multiplies (group: TileEpilogue::i8_group); i8_kernel says which instructions it uses.
  void (*quantize_a_i8)(const float* src, float* dst, int width, int64_t kc, int64_t group) = nullptr;
  void (*quantize_b_i8)(const float* src, float* dst, int width, int64_t kc, int64_t group) = nullptr;
  int i8_b_levels = 127;  // B's values lie within -i8_b_levels..i8_b_levels (A's within -127..127)
  // quantize_a_i8's panel of mr float32 rows read in place (row i at a + i * lda), without a float panel between
  // (null: pack_a, then quantize_a_i8).
  void (*pack_a_i8)(const float* a, int64_t lda, int mr, int64_t kc, int64_t group, float* dst) = nullptr;
  // quantize_b_i8's panel of nr lanes read in place from the rows of a transposed F32 or F16 B (lane j's K values at
  // b + j * ldb elements of dt), without a float panel between (null: pack_b, then quantize_b_i8).
  void (*pack_b_i8)(const void* b, DType dt, int64_t ldb, int nr, int64_t kc, int64_t group, float* dst) = nullptr;
  MicroKernel micro_i8 = nullptr;
  const char* i8_kernel = "emulated";
  // Under --conv auto, Winograd F(2x2) (frames under 8 pixels, winograd.cpp) runs on calls of at least this many
  // pixels over all frames: below, its per-call filter transform is not paid back. Under bf16 the second threshold:
  // Winograd's products stay float32, so where vdpbf16ps doubles the direct convolution's rate 4x4 frames keep it.
  int64_t winograd_f2_min_pixels = 1024;
  int64_t winograd_f2_min_pixels_bf16 = 1024;
  // Under bf16 and --conv auto, F(4x4) runs on frames at least this wide and high (0: wherever float32's runs);
  // smaller ones take the direct convolution (where vdpbf16ps doubles its rate, it beats float32 Winograd's few 4x4
  // tiles per frame).
  int64_t winograd_f4_min_frame_bf16 = 0;
  // Under Int8 and --conv auto, 3x3 convolutions take Winograd on quantised operands (winograd.h) where Winograd
  // wins in float32 and the frames are at least this wide and high (conv.cpp). Only where it beats the int8 direct
  // convolution (AVX2's vpmaddubsw); the others keep the direct convolution, whose numbers the int8 dot products and
  // their exact emulation share.
  int64_t i8_winograd_min_frame = INT64_MAX;
  // Under Int8 and --conv auto, temporal convolutions take Winograd F(2,3) on quantised transformed operands
  // (conv_temporal.cpp) where it beats the int8 direct convolution (measured on AVX2's vpmaddubsw only).
  bool i8_temporal_winograd = false;
  // Under bf16 and --conv auto, temporal convolutions take Winograd F(2,3) only on frames of at least this many
  // pixels, beyond float32's own minimum (conv_temporal.cpp; 0: none beyond it).
  int64_t temporal_winograd_min_pixels_bf16 = 0;
  // Blocking (gemm_paths.cpp: BlockRule, from the cache sizes).
  int64_t kc = 384;          // depth of a K pass
  int64_t mc = 192;          // rows of an A block (a multiple of mr)
  int64_t kc_shallow = 0;    // float32 and bf16 passes no deeper than this take A blocks of mc_shallow rows
  int64_t mc_shallow = 192;
  int64_t mc_i8 = 192;       // rows of an int8 A block
  int64_t nc = 2048;         // columns of a B block shared by the team
  // Rows of a float32 or bf16 A block for K passes of depth kc.
  int64_t a_block_rows(int64_t kc) const { return kc <= kc_shallow ? mc_shallow : mc; }
};
// The GEMM path of kernel_path(), and of any supported path (tests and benchmarks).
const GemmPath& gemm_path();
const GemmPath& gemm_path(KernelPath p);

void microkernel_portable(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                          int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void microkernel_avx2(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep);
void microkernel_avx512(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                        int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void microkernel_neon(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep);
// The NEON path's 8 x 12 tile from its float sums (row stride 16), full tiles with NEON, partial ones scalar.
void store_tile_neon(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void microkernel_avx512_bf16(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void to_bf16_pairs_avx512(float* panel, int width, int64_t kc);
void pack_a_bf16_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                        float* dst);
void pack_b_bf16_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                        float* dst);
// The C tile is written (and read, if the epilogue adds to it) after the k loop: micro-kernels start fetching it
// before (a first write misses as much as a read; AMD EPYC Zen 3 and Zen 5 class, bench gemm 4096x5120x640 and
// 16384x2560x320: 0.92-0.95x the time with this for every tile). Rows i < rows at c + i * ldc: the lines of floats 0
// and `second` of each (15 of the AVX2 tile's 16 columns, 16 of the AVX-512 tile's 32).
inline void prefetch_c_rows(const float* c, int64_t ldc, int rows, int second) {
  for (int i = 0; i < rows; ++i) {
    __builtin_prefetch(c + i * ldc, 0, 3);  // prefetcht0, as _mm_prefetch(_MM_HINT_T0)
    __builtin_prefetch(c + i * ldc + second, 0, 3);
  }
}

// ---- Int8 panels (Precision::Int8) ----
// A packed float32 panel of `width` lanes and kc rows is quantised (in place, or into a buffer apart) in groups of
// `group` rows (gemm.h's K blocks; the last group of K may be shorter). Group g becomes a region of
// i8_region(width, group) floats at float g * i8_region(...): the lanes' int8 values as quads, four k at a time in
// one 32-bit slot per lane (byte t of slot p*width + i is q(4p + t, i), offset by +128 in A's panels: the unsigned
// operand of vpdpbusd and vpmaddubsw), ceil(len/4) rows of `width` slots (values past the group's length are 0);
// then, at slot row ceil(group/4), `width` float scales and `width` int32 sums of each lane's values. A region never
// extends past the floats of its group (group > 8 when there are several), so each group is written over floats
// already read.
inline int64_t i8_slot_rows(int64_t len) { return (len + 3) / 4; }
// Float rows to leave for a panel of kc rows quantised in place: its regions' scales and sums need a few more than kc
// when kc is tiny.
inline int64_t i8_panel_rows(int64_t kc) { return (kc + 3) / 4 * 4 + 8; }
inline int64_t i8_region(int width, int64_t group) { return (i8_slot_rows(group) + 2) * width; }
struct I8Group {
  const int32_t* slots;
  const float* scale;
  const int32_t* sum;
  I8Group(const float* panel, int width, int64_t group, int64_t g) {
    const float* base = panel + g * i8_region(width, group);
    slots = reinterpret_cast<const int32_t*>(base);
    scale = base + i8_slot_rows(group) * width;
    sum = reinterpret_cast<const int32_t*>(scale + width);
  }
};
// Scale of one lane from its largest magnitude m, and the factor that quantises it (gemm.h: Precision::Int8).
// `levels` is the largest quantised magnitude: 127, or kI8LevelsAvx2B for B on the AVX2 path.
// A NaN among a lane's values makes its largest magnitude NaN (quantisers take it NaN-sticky: kept once seen, as the
// integer maximum of the magnitudes' bits does), and so its scale: every output it reaches is NaN, as in float32,
// instead of the finite values its clamped bytes would give.
inline float i8_scale(float m, int levels = 127) { return !(m <= 1e-30f) ? m / float(levels) : 0.0f; }
inline float i8_inverse(float m, int levels = 127) { return !(m <= 1e-30f) ? float(levels) / m : 0.0f; }
// x quantised with factor inv: nearbyint(x * inv) (the product rounded first) within -127..127, as a float; NaN
// stays NaN. Every scalar quantiser rounds with it (SIMD ones do the same operations).
inline float i8_round(float x, float inv) { return std::clamp(std::nearbyint(x * inv), -127.0f, 127.0f); }
// max(m, a) for magnitudes a, NaN once either is NaN.
inline float nan_sticky_max(float m, float a) { return a > m || a != a ? a : m; }
constexpr int kI8LevelsAvx2B = 63;  // vpmaddubsw's int16 pair sums of u8 x s8 stay exact (avx2/gemm.cpp)
// Scalar quantiser (any path) and the exact scalar micro-kernel of quad panels (signed bytes).
void quantize_i8_quads(const float* src, float* dst, int width, int64_t kc, int64_t group, bool unsigned_bytes);
template <int MR, int NR>
void microkernel_i8_portable(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void quantize_i8_a_avx512_vnni(const float* src, float* dst, int width, int64_t kc, int64_t group);
void quantize_i8_b_avx512_vnni(const float* src, float* dst, int width, int64_t kc, int64_t group);
void microkernel_avx512_vnni(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep);
void quantize_i8_a_avx2(const float* src, float* dst, int width, int64_t kc, int64_t group);
void quantize_i8_b_avx2(const float* src, float* dst, int width, int64_t kc, int64_t group);
void microkernel_neon_sdot(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                           int64_t ldc, int mr, int nr, const TileEpilogue& ep);
template <int MR>
void pack_a_i8_rows_avx2(const float* a, int64_t lda, int mr, int64_t kc, int64_t group, float* dst);
// The avx2 path's B panels (16 lanes, 63 levels) from a transposed F32 or F16 B (GemmPath::pack_b_i8).
void pack_b_i8_rows_avx2(const void* b, DType dt, int64_t ldb, int nr, int64_t kc, int64_t group, float* dst);
void microkernel_avx2_i8(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                         int64_t ldc, int mr, int nr, const TileEpilogue& ep);

// Emulated Bf16: x = float(bf16(x)) (nearest even) for n floats in place.
void round_to_bf16(float* p, int64_t n);
// Scalar epilogue of one tile from an MR x 16 sum (row stride 16); the partial tiles of the portable, AVX2 and
// NEON paths.
void store_tile_scalar(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep);

// Source of the A operand [M, K]: in place (F32 row-major) or packed MR rows at a time.
struct ASource {
  const float* direct = nullptr;  // non-null: F32 row-major with row stride lda, read in place
  int64_t lda = 0;
  virtual ~ASource() = default;
  // dst[k*MR + i] = A(m0 + i, k0 + k) for i < mr, 0 for mr <= i < MR, with the MR and packers of `path`.
  virtual void pack(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const = 0;
  // The same panel as bfloat16 pairs (GemmPath::to_bf16_pairs; the path has micro_bf16).
  virtual void pack_bf16_pairs(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const {
    pack(path, m0, mr, k0, kc, dst);
    path.to_bf16_pairs(dst, path.mr, kc);
  }
  // The same panel quantised for Precision::Int8 (GemmPath::quantize_a_i8, groups of `group` rows).
  virtual void pack_i8(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, int64_t group,
                       float* dst) const {
    pack(path, m0, mr, k0, kc, dst);
    path.quantize_a_i8(dst, dst, path.mr, kc, group);
  }
};

// Source of the B operand: `segments` independent column ranges of width seg_cols that share A (frames of a
// convolution); the output of segment s starts at C + s * c_seg_stride.
struct BSource {
  virtual ~BSource() = default;
  // dst[k*NR + j] = B_seg(k0 + k, n0 + j) for j < nr, 0 for nr <= j < NR, with the NR and packers of `path`.
  virtual void pack(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                    float* dst) const = 0;
  // The same panel as bfloat16 pairs (GemmPath::to_bf16_pairs; the path has micro_bf16).
  virtual void pack_bf16_pairs(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                               float* dst) const {
    pack(path, seg, k0, kc, n0, nr, dst);
    path.to_bf16_pairs(dst, path.nr, kc);
  }
  // The same panel quantised for Precision::Int8 into dst (GemmPath::quantize_b_i8, groups of `group` rows), through
  // `floats` (kc * NR floats of the caller's) where it is packed as float32 first.
  virtual void pack_i8(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, int64_t group,
                       float* dst, float* floats) const {
    pack(path, seg, k0, kc, n0, nr, floats);
    path.quantize_b_i8(floats, dst, path.nr, kc, group);
  }
};

struct GemmJob {
  int64_t M = 0, K = 0;
  int64_t segments = 1, seg_cols = 0;
  const ASource* a = nullptr;
  const BSource* b = nullptr;
  float* c = nullptr;
  int64_t ldc = 0, c_seg_stride = 0;
  Epilogue ep;  // bias per column (linear) or per row (conv)
  // GEGLU (gemm_geglu): B's panels come in pairs, value then gate (GluPairsB), and each pair's two tiles go to a
  // thread's scratch instead of C: glu_out[i, q*NR + j] = value * GELU(gate) for pair q. C is not written.
  float* glu_out = nullptr;
  int64_t glu_ld = 0;
  float* glu_scratch = nullptr;  // [M, 2D] for several K passes (the caller's, see gemm_geglu_needs_scratch)
};

// The blocked, threaded driver (threads = num_threads(), 1 inside a parallel region or for tiny jobs).
void run_gemm(const GemmJob& job);

// Operand-backed sources (any dtype, transposed or not), used by gemm() and the 1x1 convolution.
struct OperandA : ASource {
  Operand op;
  explicit OperandA(const Operand& o);
  void pack(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const override;
  void pack_bf16_pairs(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const override;
  void pack_i8(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, int64_t group,
               float* dst) const override;
};
struct OperandB : BSource {
  Operand op;
  int64_t seg_stride = 0;  // elements between segments (0 for a single matrix)
  explicit OperandB(const Operand& o, int64_t seg_stride_elems = 0) : op(o), seg_stride(seg_stride_elems) {}
  void pack(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
            float* dst) const override;
  void pack_bf16_pairs(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                       float* dst) const override;
  void pack_i8(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, int64_t group,
               float* dst, float* floats) const override;
};

// Packing primitives of each path (PackA / PackB contracts above). I8 multiplies by scale (already offset to the
// first output channel). The SIMD ones hand partial panels and K tails to the portable ones.
template <int NR>
void pack_b_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                     float* dst);
template <int MR>
void pack_a_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                     float* dst);
void pack_b_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                 float* dst);
void pack_a_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                 float* dst);
void pack_b_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                   float* dst);
void pack_a_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                   float* dst);
void pack_b_temporal_wino_avx2(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                              int64_t panel_floats);
void pack_b_temporal_wino_avx512(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                                int64_t panel_floats);
template <int NR>
void pack_b_temporal_wino_portable(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                                  int64_t panel_floats);
void temporal_wino_output_avx2(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                               const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                               int64_t row_stride);
void temporal_wino_output_avx512(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                                 const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                                 int64_t row_stride);
template <int NR>
void temporal_wino_output_portable(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                                   const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                                   int64_t row_stride);
void pack_b_neon(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                 float* dst);
void pack_a_neon(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                 float* dst);

}  // namespace egopd::gemm_detail
