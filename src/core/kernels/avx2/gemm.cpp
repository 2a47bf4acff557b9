// AVX2/FMA/F16C micro-kernel (6 x 16, 12 ymm accumulators) and packing with on-the-fly F16/BF16 conversion.
// Only reached through the avx2 and avx512 kernel paths; everything below the pragma is plain static code (no
// library inlines).
#include <algorithm>
#include <cstdint>

#include "core/kernels/gemm_internal.h"

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

#include "core/kernels/temporal_wino_pack.h"

#include "core/kernels/avx2/pack.h"
#include "core/kernels/avx2/vec_math.h"

namespace egopd::gemm_detail {

namespace {

constexpr int MR = kMrAvx2, NR = kNrAvx2;
constexpr int kPrefetchB = 16;  // k steps ahead (~100 cycles)

// ---- micro-kernel -------------------------------------------------------------------------------------------

// B rows are streamed 64 bytes per k step; the first tile of a panel finds them in L3, so fetch ahead.
#define EGOPD_PREFETCH_B(bptr) _mm_prefetch(reinterpret_cast<const char*>((bptr) + kPrefetchB * NR), _MM_HINT_T0)

#define EGOPD_FMA_ROW(c0, c1, aptr)              \
  do {                                           \
    const __m256 av = _mm256_broadcast_ss(aptr); \
    c0 = _mm256_fmadd_ps(av, b0, c0);            \
    c1 = _mm256_fmadd_ps(av, b1, c1);            \
  } while (0)

inline __m256 act_ps(Act act, __m256 v) {
  switch (act) {
    case Act::SiLU: return vmath::silu_ps(v);
    case Act::GELU: return vmath::gelu_ps(v);
    case Act::QuickGELU: return vmath::x_sigmoid_ps(v, 1.702f);
    default: return v;
  }
}

inline void prefetch_c(const float* c, int64_t ldc, int mr) { prefetch_c_rows(c, ldc, mr, NR - 1); }

// One full row of the tile: v0/v1 = columns 0-7 / 8-15 of the sum.
inline void store_row(float* c, __m256 v0, __m256 v1, int i, const TileEpilogue& ep) {
  __m256 old0 = _mm256_setzero_ps(), old1 = _mm256_setzero_ps();
  if (ep.load_c || ep.add_after) {
    old0 = _mm256_loadu_ps(c);
    old1 = _mm256_loadu_ps(c + 8);
  }
  if (ep.load_c) {
    v0 = _mm256_add_ps(v0, old0);
    v1 = _mm256_add_ps(v1, old1);
  }
  if (ep.bias_row) {
    const __m256 br = _mm256_broadcast_ss(ep.bias_row + i);
    v0 = _mm256_add_ps(v0, br);
    v1 = _mm256_add_ps(v1, br);
  }
  if (ep.bias_col) {
    v0 = _mm256_add_ps(v0, _mm256_loadu_ps(ep.bias_col));
    v1 = _mm256_add_ps(v1, _mm256_loadu_ps(ep.bias_col + 8));
  }
  if (ep.act != Act::None) {
    v0 = act_ps(ep.act, v0);
    v1 = act_ps(ep.act, v1);
  }
  if (ep.add_after) {
    v0 = _mm256_add_ps(v0, old0);
    v1 = _mm256_add_ps(v1, old1);
  }
  _mm256_storeu_ps(c, v0);
  _mm256_storeu_ps(c + 8, v1);
}

// The 6 x 16 tile (row i: v<i>0, v<i>1) into C, mr x nr of it.
__attribute__((always_inline)) inline void store_tile(float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep,
                                                      __m256 v00, __m256 v01, __m256 v10, __m256 v11, __m256 v20,
                                                      __m256 v21, __m256 v30, __m256 v31, __m256 v40, __m256 v41,
                                                      __m256 v50, __m256 v51) {
  if (mr == MR && nr == NR) {
    store_row(c, v00, v01, 0, ep);
    store_row(c + ldc, v10, v11, 1, ep);
    store_row(c + 2 * ldc, v20, v21, 2, ep);
    store_row(c + 3 * ldc, v30, v31, 3, ep);
    store_row(c + 4 * ldc, v40, v41, 4, ep);
    store_row(c + 5 * ldc, v50, v51, 5, ep);
    return;
  }
  alignas(32) float sum[MR * NR];
  const __m256 rows[MR][2] = {{v00, v01}, {v10, v11}, {v20, v21}, {v30, v31}, {v40, v41}, {v50, v51}};
  for (int i = 0; i < MR; ++i) {
    _mm256_store_ps(sum + i * NR, rows[i][0]);
    _mm256_store_ps(sum + i * NR + 8, rows[i][1]);
  }
  store_tile_scalar(sum, c, ldc, mr, nr, ep);
}

}  // namespace

void microkernel_avx2(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep) {
  __m256 c00 = _mm256_setzero_ps(), c01 = _mm256_setzero_ps(), c10 = _mm256_setzero_ps(),
         c11 = _mm256_setzero_ps(), c20 = _mm256_setzero_ps(), c21 = _mm256_setzero_ps(),
         c30 = _mm256_setzero_ps(), c31 = _mm256_setzero_ps(), c40 = _mm256_setzero_ps(),
         c41 = _mm256_setzero_ps(), c50 = _mm256_setzero_ps(), c51 = _mm256_setzero_ps();
  prefetch_c(c, ldc, mr);
  if (a_rs == 1 && a_cs == MR) {  // packed A micro-panel
    const float* ap = a;
#pragma GCC unroll 4
    for (int64_t k = 0; k < kc; ++k) {
      const __m256 b0 = _mm256_load_ps(b), b1 = _mm256_load_ps(b + 8);
      EGOPD_PREFETCH_B(b);
      EGOPD_FMA_ROW(c00, c01, ap + 0);
      EGOPD_FMA_ROW(c10, c11, ap + 1);
      EGOPD_FMA_ROW(c20, c21, ap + 2);
      EGOPD_FMA_ROW(c30, c31, ap + 3);
      EGOPD_FMA_ROW(c40, c41, ap + 4);
      EGOPD_FMA_ROW(c50, c51, ap + 5);
      ap += MR;
      b += NR;
    }
  } else {  // A in place: row i at a + i*a_rs, consecutive k at stride a_cs; rows >= mr alias the last valid row
    const int64_t last = mr - 1;
    const float* a0 = a;
    const float* a1 = a + (last < 1 ? last : 1) * a_rs;
    const float* a2 = a + (last < 2 ? last : 2) * a_rs;
    const float* a3 = a + (last < 3 ? last : 3) * a_rs;
    const float* a4 = a + (last < 4 ? last : 4) * a_rs;
    const float* a5 = a + (last < 5 ? last : 5) * a_rs;
    if (a_cs == 1) {
#pragma GCC unroll 4
      for (int64_t k = 0; k < kc; ++k) {
        const __m256 b0 = _mm256_load_ps(b), b1 = _mm256_load_ps(b + 8);
        EGOPD_PREFETCH_B(b);
        EGOPD_FMA_ROW(c00, c01, a0 + k);
        EGOPD_FMA_ROW(c10, c11, a1 + k);
        EGOPD_FMA_ROW(c20, c21, a2 + k);
        EGOPD_FMA_ROW(c30, c31, a3 + k);
        EGOPD_FMA_ROW(c40, c41, a4 + k);
        EGOPD_FMA_ROW(c50, c51, a5 + k);
        b += NR;
      }
    } else {
      for (int64_t k = 0; k < kc; ++k) {
        const __m256 b0 = _mm256_load_ps(b), b1 = _mm256_load_ps(b + 8);
        const int64_t o = k * a_cs;
        EGOPD_FMA_ROW(c00, c01, a0 + o);
        EGOPD_FMA_ROW(c10, c11, a1 + o);
        EGOPD_FMA_ROW(c20, c21, a2 + o);
        EGOPD_FMA_ROW(c30, c31, a3 + o);
        EGOPD_FMA_ROW(c40, c41, a4 + o);
        EGOPD_FMA_ROW(c50, c51, a5 + o);
        b += NR;
      }
    }
  }
  store_tile(c, ldc, mr, nr, ep, c00, c01, c10, c11, c20, c21, c30, c31, c40, c41, c50, c51);
}

#undef EGOPD_FMA_ROW
#undef EGOPD_PREFETCH_B

// ---- int8 (Precision::Int8) ------------------------------------------------------------------------------------
// vpmaddubsw multiplies unsigned bytes by signed ones into int16 pair sums, which saturate past 2^15: with A's
// bytes offset by +128 (0..255) and B's within -63..63 (gemm.h: the AVX2 path quantises B to 63 levels), a pair sum
// stays within 2 * 255 * 63 = 32130, so vpmaddwd with ones widens exact sums of four products to int32. Quad
// panels (gemm_internal.h: I8Group); each sum exceeds the true one by 128 * (B lane's sum), taken off before
// scaling. Per quad two B loads and six A broadcasts feed 12 vpmaddubsw of 32 products each (2.0x the float32
// FMA loop in isa_bench, against 1.35-1.45x for vpmaddwd on int16 pairs of 8-bit values).

namespace {

// Mask of the first n of 8 lanes (all of them for n >= 8).
inline __m256i lane_mask(int n) {
  alignas(32) static const int32_t ramp[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  return _mm256_cmpgt_epi32(_mm256_set1_epi32(n), _mm256_load_si256((const __m256i*)ramp));
}

// The lanes' running largest magnitudes, compared as integers: the same order as floats, and NaN (above inf) sticks
// (gemm_internal.h: i8_scale).
inline __m256i max_magnitude(__m256i v, __m256 x, __m256 sign) {
  return _mm256_max_epi32(v, _mm256_castps_si256(_mm256_andnot_ps(sign, x)));
}

// 8 floats x * f as int32, nearest even (as nearbyint), clamped to +-levels; `sum` gains them.
inline __m256i quantize8(__m256 x, __m256 f, int levels, __m256i& sum) {
  __m256i q = _mm256_cvtps_epi32(_mm256_mul_ps(x, f));
  q = _mm256_min_epi32(_mm256_max_epi32(q, _mm256_set1_epi32(-levels)), _mm256_set1_epi32(levels));
  sum = _mm256_add_epi32(sum, q);
  return q;
}

// One group of `len` float rows at src into its region at dst (<= src in place, else apart), values within
// -kLevels..kLevels, bytes offset by +128 when kUnsigned. In place, a chunk of 8 lanes writes slot row p over float
// row <= p of the same lanes, after rows <= 4p + 3 of them were read (the other chunk's lanes are never touched).
template <bool kUnsigned, int kLevels>
void quantize_quads(const float* src, float* dst, int width, int64_t len, int64_t group) {
  const int chunks = (width + 7) / 8;
  alignas(32) float mx[kMaxNR] = {}, scale[kMaxNR] = {}, inv[kMaxNR] = {};
  alignas(32) int32_t sums[kMaxNR] = {};
  const __m256 sign = _mm256_set1_ps(-0.0f);
  for (int ch = 0; ch < chunks; ++ch) {
    const __m256i m = lane_mask(width - 8 * ch);
    __m256i v = _mm256_setzero_si256();
    for (int64_t k = 0; k < len; ++k) v = max_magnitude(v, _mm256_maskload_ps(src + k * width + 8 * ch, m), sign);
    _mm256_store_ps(mx + 8 * ch, _mm256_castsi256_ps(v));
  }
  for (int i = 0; i < width; ++i) scale[i] = i8_scale(mx[i], kLevels), inv[i] = i8_inverse(mx[i], kLevels);
  int32_t* out = reinterpret_cast<int32_t*>(dst);
  const __m256i byte = _mm256_set1_epi32(0xff);
  for (int ch = 0; ch < chunks; ++ch) {
    const __m256i m = lane_mask(width - 8 * ch);
    const __m256 f = _mm256_load_ps(inv + 8 * ch);
    __m256i sum = _mm256_setzero_si256();
    for (int64_t p = 0; p < i8_slot_rows(len); ++p) {
      __m256i packed = _mm256_setzero_si256();
      for (int t = 0; t < 4 && 4 * p + t < len; ++t) {
        const __m256 x = _mm256_maskload_ps(src + (4 * p + t) * width + 8 * ch, m);
        const __m256i q = quantize8(x, f, kLevels, sum);
        packed = _mm256_or_si256(packed, _mm256_slli_epi32(_mm256_and_si256(q, byte), 8 * t));
      }
      if (kUnsigned) packed = _mm256_xor_si256(packed, _mm256_set1_epi32(int(0x80808080u)));
      _mm256_maskstore_epi32(out + p * width + 8 * ch, m, packed);
    }
    _mm256_store_si256((__m256i*)(sums + 8 * ch), sum);
  }
  float* tail = dst + i8_slot_rows(group) * width;
  for (int i = 0; i < width; ++i) tail[i] = scale[i];
  for (int i = 0; i < width; ++i) reinterpret_cast<int32_t*>(tail + width)[i] = sums[i];
}

template <bool kUnsigned, int kLevels>
void quantize_quad_groups(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += group)
    quantize_quads<kUnsigned, kLevels>(src + k0 * width, dst + g * i8_region(width, group), width,
                                       std::min(group, kc - k0), group);
}

alignas(32) const int16_t kOnes16[16] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};

// What a panel's lanes past its rows read: zeros for the longest group (as float32 or as F16 bits).
alignas(32) const float kZeroRow[kInt8Block] = {};
alignas(32) const uint16_t kZeroHalfRow[kInt8Block] = {};
inline const float* zero_row(const float*) { return kZeroRow; }
inline const uint16_t* zero_row(const uint16_t*) { return kZeroHalfRow; }

// 8 values of a row from p as float32: all 8 for n >= 8, else the first n and zeros (never read past them).
inline __m256 load_row8(const float* p, int n) {
  return n >= 8 ? _mm256_loadu_ps(p) : _mm256_maskload_ps(p, lane_mask(n));
}
inline __m256 load_row8(const uint16_t* p, int n) {  // F16, converted exactly
  if (n >= 8) return _mm256_cvtph_ps(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
  alignas(16) uint16_t h[8] = {};
  std::copy_n(p, n, h);
  return _mm256_cvtph_ps(_mm_load_si128(reinterpret_cast<const __m128i*>(h)));
}

// kRows (4 or 2) rows of a panel of W lanes, one group of `len` k (row r at row[r], quantising factor f[r]): their
// quads (values within -kLevels..kLevels, bytes offset by +128 when kUnsigned) into the slots from `out` (W int32 per
// slot), their signed sums into total[0 .. kRows - 1] (pack_i8_rows_avx2).
template <int W, int kRows, int kLevels, bool kUnsigned, typename T>
__attribute__((always_inline)) inline void quantize_row_block(const T* const* row, const __m256* f, int64_t len,
                                                              int32_t* out, int32_t* total) {
  const __m256i offset = _mm256_set1_epi8(char(kUnsigned ? 0x80 : 0));
  __m256i sum[kRows];
  for (int r = 0; r < kRows; ++r) sum[r] = _mm256_setzero_si256();
  for (int64_t k = 0; k < len; k += 8) {
    const int n = int(std::min<int64_t>(8, len - k));
    __m256i q[kRows];
    for (int r = 0; r < kRows; ++r) q[r] = quantize8(load_row8(row[r] + k, n), f[r], kLevels, sum[r]);
    // Per 128-bit half h (k + 4h .. k + 4h + 3): bytes [row 0 quad | row 1 quad | row 2 quad | row 3 quad].
    const __m256i w01 = _mm256_packs_epi32(q[0], q[1]);
    __m256i w23 = w01;
    if constexpr (kRows == 4) w23 = _mm256_packs_epi32(q[2], q[3]);
    const __m256i bytes = _mm256_xor_si256(_mm256_packs_epi16(w01, w23), offset);
    int32_t* slot = out + (k / 4) * W;
    if constexpr (kRows == 4) {
      _mm_storeu_si128(reinterpret_cast<__m128i*>(slot), _mm256_castsi256_si128(bytes));
      if (k + 4 < len) _mm_storeu_si128(reinterpret_cast<__m128i*>(slot + W), _mm256_extracti128_si256(bytes, 1));
    } else {
      _mm_storel_epi64(reinterpret_cast<__m128i*>(slot), _mm256_castsi256_si128(bytes));
      if (k + 4 < len) _mm_storel_epi64(reinterpret_cast<__m128i*>(slot + W), _mm256_extracti128_si256(bytes, 1));
    }
  }
  for (int r = 0; r < kRows; ++r) {
    alignas(32) int32_t lanes[8];
    _mm256_store_si256(reinterpret_cast<__m256i*>(lanes), sum[r]);
    total[r] = 0;
    for (int32_t l : lanes) total[r] += l;
  }
}

// A panel of W lanes straight from rows (lane i's values at a + i * lda, float32 or F16), quantised as the
// path's quantiser quantises the packed float panel (the same operations, so the same bytes: quantize_quads with
// kLevels and kUnsigned), without the float panel between: each row's largest magnitude over the group, then its
// bytes. Rows go four (or, last, two) at a time: 8 k of each are quantised, packed together by two saturating packs
// (values within +-127 pass them unchanged) into the row block's quads of two slots, one 16- (8-) byte store per
// slot, instead of one 4-byte store per row and quad. Lanes rows..W - 1 read zeros (scale 0) and k past the group's
// length quantise zeros.
template <int W, int kLevels, bool kUnsigned, typename T>
void pack_i8_rows_avx2(const T* a, int64_t lda, int rows, int64_t kc, int64_t group, float* dst) {
  static_assert(W % 2 == 0, "row blocks of four, then of two");
  const __m256 sign = _mm256_set1_ps(-0.0f);
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += group) {
    const int64_t len = std::min(group, kc - k0);
    int32_t* out = reinterpret_cast<int32_t*>(dst + g * i8_region(W, group));
    float* tail = dst + g * i8_region(W, group) + i8_slot_rows(group) * W;
    const T* row[W];
    __m256 f[W];
    for (int i = 0; i < W; ++i) {
      row[i] = i < rows ? a + i * lda + k0 : zero_row(a);
      float scale = 0.0f;
      f[i] = _mm256_setzero_ps();
      if (i < rows) {
        __m256i v = _mm256_setzero_si256();
        // The next panel's row meanwhile: rows of a few hundred values are too short a stream for the hardware
        // prefetcher to pick up before they end.
        const T* next = row[i] + W * lda;
        for (int64_t j = 0; j < len; j += 64 / int64_t(sizeof(T)))
          _mm_prefetch(reinterpret_cast<const char*>(next + j), _MM_HINT_T0);
        for (int64_t k = 0; k < len; k += 8)
          v = max_magnitude(v, load_row8(row[i] + k, int(std::min<int64_t>(8, len - k))), sign);
        alignas(32) float lane_max[8];
        _mm256_store_ps(lane_max, _mm256_castsi256_ps(v));
        float m = 0.0f;
        for (float l : lane_max) m = nan_sticky_max(m, l);
        scale = i8_scale(m, kLevels);
        f[i] = _mm256_set1_ps(i8_inverse(m, kLevels));
      }
      tail[i] = scale;
    }
    int32_t* const total = reinterpret_cast<int32_t*>(tail + W);
    int i = 0;
    for (; i + 4 <= W; i += 4)
      quantize_row_block<W, 4, kLevels, kUnsigned>(row + i, f + i, len, out + i, total + i);
    if (i < W) quantize_row_block<W, 2, kLevels, kUnsigned>(row + i, f + i, len, out + i, total + i);
  }
}

}  // namespace

void quantize_i8_a_avx2(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  quantize_quad_groups<true, 127>(src, dst, width, kc, group);
}
void quantize_i8_b_avx2(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  quantize_quad_groups<false, kI8LevelsAvx2B>(src, dst, width, kc, group);
}

template <int MR>
void pack_a_i8_rows_avx2(const float* a, int64_t lda, int mr, int64_t kc, int64_t group, float* dst) {
  pack_i8_rows_avx2<MR, 127, true>(a, lda, mr, kc, group, dst);
}
template void pack_a_i8_rows_avx2<kMrAvx2>(const float*, int64_t, int, int64_t, int64_t, float*);
template void pack_a_i8_rows_avx2<kMrAvx512>(const float*, int64_t, int, int64_t, int64_t, float*);

void pack_b_i8_rows_avx2(const void* b, DType dt, int64_t ldb, int nr, int64_t kc, int64_t group, float* dst) {
  if (dt == DType::F16)
    return pack_i8_rows_avx2<NR, kI8LevelsAvx2B, false>(static_cast<const uint16_t*>(b), ldb, nr, kc, group, dst);
  pack_i8_rows_avx2<NR, kI8LevelsAvx2B, false>(static_cast<const float*>(b), ldb, nr, kc, group, dst);
}

// All six rows at once: twelve accumulators (ymm0-11), two B vectors (ymm12-13), the A broadcast (ymm14) and a
// product (ymm15) fill the 16 registers, so the ones of the widening come from memory and the quad loop is assembly
// (with intrinsics GCC spilled accumulators; isa_bench: this 6 x 16 loop runs as fast as a 5 x 16 one with the ones
// in a register). The int32 sums of a group go to `acc` (row i at acc + 16 i).
#define EGOPD_ROW_ASM(i, c0, c1)                                    \
  "vpbroadcastd " #i "*4(%[a]), %%ymm14\n\t"                        \
  "vpmaddubsw %%ymm12, %%ymm14, %%ymm15\n\t"                        \
  "vpmaddwd %[ones], %%ymm15, %%ymm15\n\t"                          \
  "vpaddd %%ymm15, %%ymm" #c0 ", %%ymm" #c0 "\n\t"                  \
  "vpmaddubsw %%ymm13, %%ymm14, %%ymm15\n\t"                        \
  "vpmaddwd %[ones], %%ymm15, %%ymm15\n\t"                          \
  "vpaddd %%ymm15, %%ymm" #c1 ", %%ymm" #c1 "\n\t"
#define EGOPD_STORE_ASM(i, c0, c1)                 \
  "vmovdqa %%ymm" #c0 ", " #i "*64(%[acc])\n\t"    \
  "vmovdqa %%ymm" #c1 ", " #i "*64+32(%[acc])\n\t"
void microkernel_avx2_i8(int64_t kc, const float* a_panel, int64_t, int64_t, const float* b_panel, float* c,
                         int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  static_assert(MR == 6 && NR == 16, "the assembly below is the 6 x 16 tile");
  prefetch_c(c, ldc, mr);
  alignas(32) float sum[MR * NR];  // float sums of the groups before the last (gemm_internal.h: I8Group)
  alignas(32) int32_t acc[MR * NR];
  const __m256 zero = _mm256_setzero_ps();
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += ep.i8_group) {
    const I8Group pa(a_panel, MR, ep.i8_group, g), pb(b_panel, NR, ep.i8_group, g);
    int64_t quads = i8_slot_rows(std::min(ep.i8_group, kc - k0));
    const int32_t* a = pa.slots;
    const int32_t* b = pb.slots;
    asm volatile(
        "vpxor %%xmm0, %%xmm0, %%xmm0\n\t"
        "vmovdqa %%ymm0, %%ymm1\n\t" "vmovdqa %%ymm0, %%ymm2\n\t" "vmovdqa %%ymm0, %%ymm3\n\t"
        "vmovdqa %%ymm0, %%ymm4\n\t" "vmovdqa %%ymm0, %%ymm5\n\t" "vmovdqa %%ymm0, %%ymm6\n\t"
        "vmovdqa %%ymm0, %%ymm7\n\t" "vmovdqa %%ymm0, %%ymm8\n\t" "vmovdqa %%ymm0, %%ymm9\n\t"
        "vmovdqa %%ymm0, %%ymm10\n\t" "vmovdqa %%ymm0, %%ymm11\n\t"
        "test %[n], %[n]\n\t"
        "jz 2f\n\t"
        "1:\n\t"
        "vmovdqu (%[b]), %%ymm12\n\t"
        "vmovdqu 32(%[b]), %%ymm13\n\t"
        "prefetcht0 1024(%[b])\n\t"  // 16 quad rows ahead, as the float32 kernel's kPrefetchB
        EGOPD_ROW_ASM(0, 0, 1) EGOPD_ROW_ASM(1, 2, 3) EGOPD_ROW_ASM(2, 4, 5)
        EGOPD_ROW_ASM(3, 6, 7) EGOPD_ROW_ASM(4, 8, 9) EGOPD_ROW_ASM(5, 10, 11)
        "add $24, %[a]\n\t"
        "add $64, %[b]\n\t"
        "dec %[n]\n\t"
        "jnz 1b\n\t"
        "2:\n\t"
        EGOPD_STORE_ASM(0, 0, 1) EGOPD_STORE_ASM(1, 2, 3) EGOPD_STORE_ASM(2, 4, 5)
        EGOPD_STORE_ASM(3, 6, 7) EGOPD_STORE_ASM(4, 8, 9) EGOPD_STORE_ASM(5, 10, 11)
        : [a] "+r"(a), [b] "+r"(b), [n] "+r"(quads)
        : [acc] "r"(acc), [ones] "m"(kOnes16)
        : "cc", "memory", "xmm0", "xmm1", "xmm2", "xmm3", "xmm4", "xmm5", "xmm6", "xmm7", "xmm8", "xmm9", "xmm10",
          "xmm11", "xmm12", "xmm13", "xmm14", "xmm15");
    // Each sum exceeds the true one by 128 * (the B lane's sum): A's bytes are offset to unsigned.
    const __m256i corr[2] = {_mm256_slli_epi32(_mm256_loadu_si256((const __m256i*)pb.sum), 7),
                             _mm256_slli_epi32(_mm256_loadu_si256((const __m256i*)(pb.sum + 8)), 7)};
    const __m256 sb[2] = {_mm256_loadu_ps(pb.scale), _mm256_loadu_ps(pb.scale + 8)};
    // Row i, columns 8 h.. 8 h + 7 of the float sum with this group: every path adds a group as
    // sum = fma(float(int32 sum - correction), s_row * s_col, sum), explicit, so that no path's compiler
    // contraction makes the results differ (the first group adds to +0).
    const auto with_group = [&](int i, int h) {
      const __m256i q = _mm256_sub_epi32(_mm256_load_si256((const __m256i*)(acc + i * NR + 8 * h)), corr[h]);
      const __m256 before = g > 0 ? _mm256_load_ps(sum + i * NR + 8 * h) : zero;
      return _mm256_fmadd_ps(_mm256_cvtepi32_ps(q), _mm256_mul_ps(_mm256_broadcast_ss(pa.scale + i), sb[h]), before);
    };
    if (k0 + ep.i8_group >= kc)  // the last group: from registers into C, not through `sum`
      return store_tile(c, ldc, mr, nr, ep, with_group(0, 0), with_group(0, 1), with_group(1, 0), with_group(1, 1),
                        with_group(2, 0), with_group(2, 1), with_group(3, 0), with_group(3, 1), with_group(4, 0),
                        with_group(4, 1), with_group(5, 0), with_group(5, 1));
    for (int i = 0; i < MR; ++i)
      for (int h = 0; h < 2; ++h) _mm256_store_ps(sum + i * NR + 8 * h, with_group(i, h));
  }
  store_tile(c, ldc, mr, nr, ep, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero, zero);  // kc = 0
}

#undef EGOPD_STORE_ASM
#undef EGOPD_ROW_ASM

// ---- packing --------------------------------------------------------------------------------------------------

namespace {

using pack_avx2::load8;
using pack_avx2::transpose8;

// B(k, j) = p[k*ld + j] (* scale[j]), all 16 columns valid.
__attribute__((always_inline)) inline void pack_b_rows16(const void* p, DType dt, int64_t ld, const float* scale,
                                                         int64_t kc, float* dst) {
  const int64_t es = dt == DType::F32 ? 4 : dt == DType::I8 ? 1 : 2;
  const __m256 s0 = scale ? _mm256_loadu_ps(scale) : _mm256_set1_ps(1.0f);
  const __m256 s1 = scale ? _mm256_loadu_ps(scale + 8) : _mm256_set1_ps(1.0f);
  for (int64_t k = 0; k < kc; ++k) {
    // The next panel reads the following bytes of the same rows (one stream per row): fetch them into L2.
    _mm_prefetch(static_cast<const char*>(p) + (k * ld + NR) * es, _MM_HINT_T1);
    __m256 v0 = load8(p, dt, k * ld), v1 = load8(p, dt, k * ld + 8);
    if (scale) {
      v0 = _mm256_mul_ps(v0, s0);
      v1 = _mm256_mul_ps(v1, s1);
    }
    _mm256_store_ps(dst + k * NR, v0);
    _mm256_store_ps(dst + k * NR + 8, v1);
  }
}

// B(k, j) = p[j*ld + k] (* scale[j]), all 16 columns valid: 8 x 8 register transposes; returns the k handled
// (a multiple of 8).
__attribute__((always_inline)) inline int64_t pack_b_cols16(const void* p, DType dt, int64_t ld, const float* scale,
                                                            int64_t kc, float* dst) {
  const int64_t k8 = kc / 8 * 8;
  for (int64_t k = 0; k < k8; k += 8)
    for (int g = 0; g < 2; ++g) {
      __m256 r[8];
      for (int j = 0; j < 8; ++j) {
        r[j] = load8(p, dt, (g * 8 + j) * ld + k);
        if (scale) r[j] = _mm256_mul_ps(r[j], _mm256_broadcast_ss(scale + g * 8 + j));
      }
      transpose8(r);
      for (int q = 0; q < 8; ++q) _mm256_store_ps(dst + (k + q) * NR + g * 8, r[q]);
    }
  return k8;
}

// A(i, k) = p[i*ld + k] (* scale[i]), 6 rows valid: 8 x 8 transposes of 6 rows (+2 zero rows); returns the k
// handled.
__attribute__((always_inline)) inline int64_t pack_a_rows6(const void* p, DType dt, int64_t ld, const float* scale,
                                                           int64_t kc, float* dst) {
  const int64_t k8 = kc / 8 * 8;
  for (int64_t k = 0; k < k8; k += 8) {
    __m256 r[8];
    for (int i = 0; i < MR; ++i) {
      r[i] = load8(p, dt, i * ld + k);
      if (scale) r[i] = _mm256_mul_ps(r[i], _mm256_broadcast_ss(scale + i));
    }
    r[6] = r[7] = _mm256_setzero_ps();
    transpose8(r);
    for (int q = 0; q < 8; ++q) {  // column q: lanes 0-5 are the 6 rows
      float* d = dst + (k + q) * MR;
      _mm_storeu_ps(d, _mm256_castps256_ps128(r[q]));
      _mm_storel_pi(reinterpret_cast<__m64*>(d + 4), _mm256_extractf128_ps(r[q], 1));
    }
  }
  return k8;
}

bool packable(DType dt) { return dt == DType::F32 || dt == DType::F16 || dt == DType::BF16 || dt == DType::I8; }
int64_t elem_size(DType dt) { return dt == DType::F32 ? 4 : dt == DType::I8 ? 1 : 2; }

}  // namespace

void pack_b_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                 float* dst) {
  if (nr != NR || !packable(dt)) return pack_b_portable<NR>(p, dt, ld, trans, scale, kc, nr, dst);
  if (!trans) {
    switch (dt) {
      case DType::F32: return pack_b_rows16(p, DType::F32, ld, nullptr, kc, dst);
      case DType::F16: return pack_b_rows16(p, DType::F16, ld, nullptr, kc, dst);
      case DType::BF16: return pack_b_rows16(p, DType::BF16, ld, nullptr, kc, dst);
      default: return pack_b_rows16(p, DType::I8, ld, scale, kc, dst);
    }
  }
  int64_t done;
  switch (dt) {
    case DType::F32: done = pack_b_cols16(p, DType::F32, ld, nullptr, kc, dst); break;
    case DType::F16: done = pack_b_cols16(p, DType::F16, ld, nullptr, kc, dst); break;
    case DType::BF16: done = pack_b_cols16(p, DType::BF16, ld, nullptr, kc, dst); break;
    default: done = pack_b_cols16(p, DType::I8, ld, scale, kc, dst); break;
  }
  if (done < kc)
    pack_b_portable<NR>(static_cast<const char*>(p) + done * elem_size(dt), dt, ld, true, scale, kc - done, nr,
                    dst + done * NR);
}

void pack_a_avx2(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                 float* dst) {
  if (trans || mr != MR || !packable(dt)) return pack_a_portable<MR>(p, dt, ld, trans, scale, mr, kc, dst);
  int64_t done;
  switch (dt) {
    case DType::F32: done = pack_a_rows6(p, DType::F32, ld, nullptr, kc, dst); break;
    case DType::F16: done = pack_a_rows6(p, DType::F16, ld, nullptr, kc, dst); break;
    case DType::BF16: done = pack_a_rows6(p, DType::BF16, ld, nullptr, kc, dst); break;
    default: done = pack_a_rows6(p, DType::I8, ld, scale, kc, dst); break;
  }
  if (done < kc)
    pack_a_portable<MR>(static_cast<const char*>(p) + done * elem_size(dt), dt, ld, false, scale, mr, kc - done,
                    dst + done * MR);
}

void pack_b_temporal_wino_avx2(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                              int64_t panel_floats) {
  temporal_wino_pack<NR>(m, in, ld, kc, nr, dst, panel_floats);
}

void temporal_wino_output_avx2(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                               const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                               int64_t row_stride) {
  temporal_wino_out<NR>(m, prod, prod_stride, frames, mr, nr, bias, accumulate, dst, frame_stride, row_stride);
}

}  // namespace egopd::gemm_detail
