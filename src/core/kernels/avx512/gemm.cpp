// AVX-512 micro-kernel (12 x 32: twenty-four zmm accumulators; per k two B loads and twelve broadcast A elements
// feed 24 FMAs) and packing with F16/BF16/I8 conversion in registers. Partial tiles use masked loads and stores (no
// scalar tails). Only reached through the avx512 kernel path; everything below the pragma is plain static code.
#include <algorithm>
#include <cstdint>
#include <type_traits>

#include "core/kernels/gemm_internal.h"

#include "core/kernels/avx512/isa.h"

#include "core/kernels/temporal_wino_pack.h"

#include "core/kernels/avx2/pack.h"
#include "core/kernels/avx512/tile.h"

namespace egopd::gemm_detail {

namespace {

constexpr int kPrefetchB = 8;  // k steps ahead

#define EGOPD_STORE(i)                                                                                 \
  _mm512_store_ps(sum + (i) * NR, first ? c##i##0 : _mm512_add_ps(_mm512_load_ps(sum + (i) * NR), c##i##0)); \
  _mm512_store_ps(sum + (i) * NR + 16,                                                                 \
                  first ? c##i##1 : _mm512_add_ps(_mm512_load_ps(sum + (i) * NR + 16), c##i##1));

// The k loop: over a packed A micro-panel (a[k*MR + i]), or over A in place (row i at a + i*lda, all MR rows
// valid; two base pointers and the offsets 0..5 lda keep every address in registers). Writes the tile's sum
// (row-major, MR x NR) when `first`, else adds to it.
template <bool kInPlace>
__attribute__((always_inline)) inline void k_loop(int64_t kc, const float* a, int64_t lda, const float* b,
                                                  float* sum, bool first) {
  EGOPD_ROWS(EGOPD_DECLARE)
  const int64_t l2 = 2 * lda, l3 = 3 * lda, l4 = 4 * lda, l5 = 5 * lda;
  const float* lo = a;            // rows 0-5
  const float* hi = a + 6 * lda;  // rows 6-11
  for (int64_t k = 0; k < kc; ++k) {
    const __m512 b0 = _mm512_load_ps(b), b1 = _mm512_load_ps(b + 16);
    _mm_prefetch(reinterpret_cast<const char*>(b + kPrefetchB * NR), _MM_HINT_T0);
    _mm_prefetch(reinterpret_cast<const char*>(b + kPrefetchB * NR + 16), _MM_HINT_T0);
    if constexpr (kInPlace) {
      const int64_t off[6] = {0, lda, l2, l3, l4, l5};
#define A_AT(i) ((i) < 6 ? lo[off[(i) % 6]] : hi[off[(i) % 6]])
      EGOPD_ROWS(EGOPD_FMA)
#undef A_AT
      ++lo, ++hi;
    } else {
#define A_AT(i) a[(i)]
      EGOPD_ROWS(EGOPD_FMA)
#undef A_AT
      a += MR;
    }
    b += NR;
  }
  EGOPD_ROWS(EGOPD_STORE)
}

#undef EGOPD_STORE
#undef EGOPD_FMA

}  // namespace

void microkernel_avx512(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                        int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  prefetch_c(c, ldc, mr);
  alignas(64) float sum[MR * NR];
  if (a_rs == 1 && a_cs == MR) {
    k_loop<false>(kc, a, 0, b, sum, true);
  } else if (a_cs == 1 && mr == MR) {
    k_loop<true>(kc, a, a_rs, b, sum, true);
  } else {  // a partial row panel in place (the last of a matrix): pack it here, 128 k at a time
    alignas(64) float panel[128 * MR];
    for (int64_t k0 = 0; k0 < kc || k0 == 0; k0 += 128) {
      const int64_t n = std::min<int64_t>(128, kc - k0);
      for (int64_t k = 0; k < n; ++k)
        for (int i = 0; i < MR; ++i) panel[k * MR + i] = i < mr ? a[i * a_rs + (k0 + k) * a_cs] : 0.0f;
      k_loop<false>(n, panel, 0, b + k0 * NR, sum, k0 == 0);
    }
  }
  store_tile(sum, c, ldc, mr, nr, ep);
}

// ---- bfloat16 (Precision::Bf16 on CPUs with AVX512-BF16) --------------------------------------------------------
// vdpbf16ps: lane j += a.lo * b.lo + a.hi * b.hi, the products exact in float32. Panels hold k pairs (see
// GemmPath::to_bf16_pairs), 32 products per instruction.

// EGOPD_SLOT_LOOP(n): n rows of the 32-bit slots of the A and B panels at a and b (bf16 pairs, int8 quads); per
// row two B loads and twelve A broadcasts feed 24 instructions EGOPD_DOT_INSN (defined at each use) into
// c<i>0, c<i>1. The instructions are inline assembly: with their intrinsics GCC 12 copies each accumulator before
// the instruction (its destination is also its input) and spills the tile to the stack (vpdpbusd: 3.6x slower).
// The emulated build (isa.h) has no such instructions: there, the intrinsic EGOPD_DOT_INTRINSIC instead.
#if defined(EGOPD_EMULATE_AVX512)
#define EGOPD_DOT_ONE(acc, x, y) acc = EGOPD_DOT_INTRINSIC(acc, x, y)
#else
#define EGOPD_DOT_ONE(acc, x, y) asm(EGOPD_DOT_INSN " %[b], %[a], %[c]" : [c] "+v"(acc) : [a] "v"(x), [b] "v"(y))
#endif
#define EGOPD_DOT(i)                                                                     \
  {                                                                                      \
    const __m512i av = _mm512_set1_epi32(int(a[(i)]));                                   \
    EGOPD_DOT_ONE(c##i##0, av, b0);                                                      \
    EGOPD_DOT_ONE(c##i##1, av, b1);                                                      \
  }
#define EGOPD_SLOT_LOOP(n)                                                               \
  for (int64_t p = 0, rows_ = (n); p < rows_; ++p) {                                     \
    const __m512i b0 = _mm512_loadu_si512(b), b1 = _mm512_loadu_si512(b + 16);          \
    _mm_prefetch(reinterpret_cast<const char*>(b + kPrefetchB * NR), _MM_HINT_T0);       \
    _mm_prefetch(reinterpret_cast<const char*>(b + kPrefetchB * NR + 16), _MM_HINT_T0);  \
    EGOPD_ROWS(EGOPD_DOT)                                                                \
    a += MR;                                                                             \
    b += NR;                                                                             \
  }
#define EGOPD_DOT_INSN "vdpbf16ps"
#define EGOPD_DOT_INTRINSIC(c, a, b) _mm512_dpbf16_ps(c, (__m512bh)(a), (__m512bh)(b))
#define EGOPD_STORE(i)                   \
  _mm512_store_ps(sum + (i) * NR, c##i##0); \
  _mm512_store_ps(sum + (i) * NR + 16, c##i##1);

EGOPD_TARGET_BF16 void microkernel_avx512_bf16(int64_t kc, const float* a_panel, int64_t, int64_t,
                                               const float* b_panel, float* c, int64_t ldc, int mr, int nr,
                                               const TileEpilogue& ep) {
  prefetch_c(c, ldc, mr);
  const uint32_t* a = reinterpret_cast<const uint32_t*>(a_panel);
  const uint32_t* b = reinterpret_cast<const uint32_t*>(b_panel);
  EGOPD_ROWS(EGOPD_DECLARE)
  EGOPD_SLOT_LOOP((kc + 1) / 2)
  alignas(64) float sum[MR * NR];
  EGOPD_ROWS(EGOPD_STORE)
  store_tile(sum, c, ldc, mr, nr, ep);
}

#undef EGOPD_DOT_INSN
#undef EGOPD_DOT_INTRINSIC
#undef EGOPD_STORE

EGOPD_TARGET_BF16 void to_bf16_pairs_avx512(float* panel, int width, int64_t kc) {
  // In place: pair p is written over float rows <= p, all of them read before (row 0 by this very step, whose
  // chunks are each loaded before they are overwritten).
  uint32_t* out = reinterpret_cast<uint32_t*>(panel);
  for (int64_t p = 0, pairs = (kc + 1) / 2; p < pairs; ++p) {
    const float* r0 = panel + 2 * p * width;
    const bool has_odd = 2 * p + 1 < kc;
    for (int j = 0; j < width; j += 16) {
      const __mmask16 m = lanes(width - j);
      const __m512 lo = _mm512_maskz_loadu_ps(m, r0 + j);
      const __m512 hi = has_odd ? _mm512_maskz_loadu_ps(m, r0 + width + j) : _mm512_setzero_ps();
      const __m512i lo16 = _mm512_cvtepu16_epi32((__m256i)_mm512_cvtneps_pbh(lo));
      const __m512i hi16 = _mm512_cvtepu16_epi32((__m256i)_mm512_cvtneps_pbh(hi));
      _mm512_mask_storeu_epi32(out + p * width + j, m, _mm512_or_si512(lo16, _mm512_slli_epi32(hi16, 16)));
    }
  }
}

// ---- int8 (Precision::Int8 on CPUs with AVX512-VNNI) --------------------------------------------------------
// vpdpbusd: lane j += sum over t of u8(a byte t) * s8(b byte t). Quad panels (gemm_internal.h: I8Group): A's bytes
// offset by +128 (unsigned), B's signed, so each sum exceeds the true one by 128 * (B lane's sum), taken off
// before scaling. Per quad two B loads and twelve A broadcasts feed 24 instructions of 64 products each.

namespace {

// One group of `len` float rows at src into its region at dst (<= src in place, else apart) (quads; the order of quantize_i8_quads per 16
// lanes, so the same in-place argument holds).
template <bool kUnsigned>
__attribute__((always_inline)) inline void quantize_quads(const float* src, float* dst, int width, int64_t len,
                                                          int64_t group) {
  const int chunks = (width + 15) / 16;
  alignas(64) float mx[kMaxNR] = {}, scale[kMaxNR] = {}, inv[kMaxNR] = {};
  for (int ch = 0; ch < chunks; ++ch) {
    const __mmask16 m = lanes(width - 16 * ch);
    // Magnitudes compared as integers: the same order, and NaN (above inf) sticks (gemm_internal.h: i8_scale).
    __m512i v = _mm512_setzero_si512();
    for (int64_t k = 0; k < len; ++k)
      v = _mm512_max_epi32(v, _mm512_castps_si512(_mm512_abs_ps(_mm512_maskz_loadu_ps(m, src + k * width + 16 * ch))));
    _mm512_store_ps(mx + 16 * ch, _mm512_castsi512_ps(v));
  }
  for (int i = 0; i < width; ++i) scale[i] = i8_scale(mx[i]), inv[i] = i8_inverse(mx[i]);
  int32_t* out = reinterpret_cast<int32_t*>(dst);
  const __m512i lo = _mm512_set1_epi32(-127), hi = _mm512_set1_epi32(127), byte = _mm512_set1_epi32(0xff);
  __m512i sum[2] = {_mm512_setzero_si512(), _mm512_setzero_si512()};
  for (int64_t p = 0; p < i8_slot_rows(len); ++p)
    for (int ch = 0; ch < chunks; ++ch) {
      const __mmask16 m = lanes(width - 16 * ch);
      const __m512 f = _mm512_load_ps(inv + 16 * ch);
      __m512i packed = _mm512_setzero_si512();
      for (int t = 0; t < 4 && 4 * p + t < len; ++t) {
        const __m512 x = _mm512_maskz_loadu_ps(m, src + (4 * p + t) * width + 16 * ch);
        __m512i q = _mm512_cvtps_epi32(_mm512_mul_ps(x, f));  // nearest even, as nearbyint
        q = _mm512_min_epi32(_mm512_max_epi32(q, lo), hi);
        sum[ch] = _mm512_add_epi32(sum[ch], q);
        packed = _mm512_or_si512(packed, _mm512_slli_epi32(_mm512_and_si512(q, byte), 8 * t));
      }
      if (kUnsigned) packed = _mm512_xor_si512(packed, _mm512_set1_epi32(int(0x80808080u)));
      _mm512_mask_storeu_epi32(out + p * width + 16 * ch, m, packed);
    }
  float* tail = dst + i8_slot_rows(group) * width;
  for (int ch = 0; ch < chunks; ++ch) {
    const __mmask16 m = lanes(width - 16 * ch);
    _mm512_mask_storeu_ps(tail + 16 * ch, m, _mm512_load_ps(scale + 16 * ch));
    _mm512_mask_storeu_epi32(tail + width + 16 * ch, m, sum[ch]);
  }
}

template <bool kUnsigned>
void quantize_quad_groups(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += group)
    quantize_quads<kUnsigned>(src + k0 * width, dst + g * i8_region(width, group), width,
                              std::min(group, kc - k0), group);
}

}  // namespace

void quantize_i8_a_avx512_vnni(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  quantize_quad_groups<true>(src, dst, width, kc, group);
}
void quantize_i8_b_avx512_vnni(const float* src, float* dst, int width, int64_t kc, int64_t group) {
  quantize_quad_groups<false>(src, dst, width, kc, group);
}

#define EGOPD_DECLARE_INT(i) __m512i c##i##0 = _mm512_setzero_si512(), c##i##1 = _mm512_setzero_si512();
#define EGOPD_DOT_INSN "vpdpbusd"
#define EGOPD_DOT_INTRINSIC(c, a, b) _mm512_dpbusd_epi32(c, a, b)
// sum = fma(float(int32 sum - correction), s_row * s_col, sum), as on every path (gemm_i8.cpp).
#define EGOPD_SCALE(i)                                                                                     \
  {                                                                                                        \
    const __m512 sa = _mm512_set1_ps(pa.scale[(i)]);                                                       \
    const __m512 old0 = g > 0 ? _mm512_load_ps(sum + (i) * NR) : _mm512_setzero_ps();                      \
    const __m512 old1 = g > 0 ? _mm512_load_ps(sum + (i) * NR + 16) : _mm512_setzero_ps();                 \
    _mm512_store_ps(sum + (i) * NR, _mm512_fmadd_ps(_mm512_cvtepi32_ps(_mm512_sub_epi32(c##i##0, corr0)),  \
                                                    _mm512_mul_ps(sa, sb0), old0));                        \
    _mm512_store_ps(sum + (i) * NR + 16, _mm512_fmadd_ps(_mm512_cvtepi32_ps(_mm512_sub_epi32(c##i##1, corr1)), \
                                                         _mm512_mul_ps(sa, sb1), old1));                   \
  }

EGOPD_TARGET_VNNI void microkernel_avx512_vnni(int64_t kc, const float* a_panel, int64_t, int64_t,
                                               const float* b_panel, float* c, int64_t ldc, int mr, int nr,
                                               const TileEpilogue& ep) {
  prefetch_c(c, ldc, mr);
  // Float sums of the groups (gemm_internal.h: I8Group) in `sum`, the int32 ones of a group in registers.
  alignas(64) float sum[MR * NR];
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += ep.i8_group) {
    const I8Group pa(a_panel, MR, ep.i8_group, g), pb(b_panel, NR, ep.i8_group, g);
    const int32_t* a = pa.slots;
    const int32_t* b = pb.slots;
    EGOPD_ROWS(EGOPD_DECLARE_INT)
    EGOPD_SLOT_LOOP(i8_slot_rows(std::min(ep.i8_group, kc - k0)))
    // Each sum exceeds the true one by 128 * (the B lane's sum): A's bytes are offset to unsigned.
    const __m512i corr0 = _mm512_slli_epi32(_mm512_loadu_si512(pb.sum), 7);
    const __m512i corr1 = _mm512_slli_epi32(_mm512_loadu_si512(pb.sum + 16), 7);
    const __m512 sb0 = _mm512_loadu_ps(pb.scale), sb1 = _mm512_loadu_ps(pb.scale + 16);
    EGOPD_ROWS(EGOPD_SCALE)
  }
  store_tile(sum, c, ldc, mr, nr, ep);
}

#undef EGOPD_SCALE
#undef EGOPD_DOT_INSN
#undef EGOPD_DOT_INTRINSIC
#undef EGOPD_DECLARE_INT
#undef EGOPD_SLOT_LOOP
#undef EGOPD_DOT
#undef EGOPD_DECLARE
#undef EGOPD_ROWS

// ---- packing --------------------------------------------------------------------------------------------------

namespace {

using pack_avx2::load8;
using pack_avx2::transpose8;

// 16 consecutive elements (those of mask m, the rest zero) as float32 (I8: before its scale).
__attribute__((always_inline)) inline __m512 load16(const void* p, DType dt, int64_t idx, __mmask16 m) {
  if (dt == DType::F32) return _mm512_maskz_loadu_ps(m, static_cast<const float*>(p) + idx);
  if (dt == DType::I8)
    return _mm512_cvtepi32_ps(_mm512_cvtepi8_epi32(_mm_maskz_loadu_epi8(m, static_cast<const int8_t*>(p) + idx)));
  const __m256i h = _mm256_maskz_loadu_epi16(m, static_cast<const uint16_t*>(p) + idx);
  if (dt == DType::F16) return _mm512_cvtph_ps(h);
  return _mm512_castsi512_ps(_mm512_slli_epi32(_mm512_cvtepu16_epi32(h), 16));  // BF16
}

// dst[k*W + j] = p[k*ld + j] (* scale[j]) for j < n, 0 for n <= j < W: (masked) loads of consecutive lanes.
template <int W>
__attribute__((always_inline)) inline void pack_contiguous(const void* p, DType dt, int64_t ld, const float* scale,
                                                           int64_t kc, int n, float* dst) {
  constexpr int kChunks = (W + 15) / 16;
  const int64_t es = dt == DType::F32 ? 4 : dt == DType::I8 ? 1 : 2;
  __mmask16 in[kChunks], out[kChunks];
  __m512 s[kChunks];
  for (int q = 0; q < kChunks; ++q) {
    in[q] = lanes(n - 16 * q);
    out[q] = lanes(W - 16 * q);
    s[q] = scale ? _mm512_maskz_loadu_ps(in[q], scale + 16 * q) : _mm512_set1_ps(1.0f);
  }
  for (int64_t k = 0; k < kc; ++k) {
    // The next panel reads the following bytes of the same rows (one stream per row): fetch them into L2.
    _mm_prefetch(static_cast<const char*>(p) + (k * ld + W) * es, _MM_HINT_T1);
    for (int q = 0; q < kChunks; ++q) {
      __m512 v = load16(p, dt, k * ld + 16 * q, in[q]);
      if (scale) v = _mm512_mul_ps(v, s[q]);
      _mm512_mask_storeu_ps(dst + k * W + 16 * q, out[q], v);
    }
  }
}

// dst[k*W + j] = p[j*ld + k] (* scale[j]), all W lanes valid: 8 x 8 register transposes of 8 lanes at a time;
// returns the k handled (a multiple of 8).
template <int W>
__attribute__((always_inline)) inline int64_t pack_strided(const void* p, DType dt, int64_t ld, const float* scale,
                                                           int64_t kc, float* dst) {
  const int64_t k8 = kc / 8 * 8;
  for (int64_t k = 0; k < k8; k += 8)
    for (int g = 0; g < W; g += 8) {
      const int rows = std::min(8, W - g);
      __m256 r[8];
      for (int j = 0; j < 8; ++j) {
        r[j] = j < rows ? load8(p, dt, (g + j) * ld + k) : _mm256_setzero_ps();
        if (scale && j < rows) r[j] = _mm256_mul_ps(r[j], _mm256_broadcast_ss(scale + g + j));
      }
      transpose8(r);
      const __mmask8 m = __mmask8((1u << rows) - 1u);
      for (int q = 0; q < 8; ++q) _mm256_mask_storeu_ps(dst + (k + q) * W + g, m, r[q]);
    }
  return k8;
}

bool packable(DType dt) { return dt == DType::F32 || dt == DType::F16 || dt == DType::BF16 || dt == DType::I8; }
int64_t elem_size(DType dt) { return dt == DType::F32 ? 4 : dt == DType::I8 ? 1 : 2; }

// f(std::integral_constant<DType, dt>{}, scale) for a packable dt, so that the inlined packers see the dtype as a
// constant; only I8 carries a scale.
template <class F>
__attribute__((always_inline)) inline auto with_packable_dtype(DType dt, const float* scale, F f) {
  switch (dt) {
    case DType::F32: return f(std::integral_constant<DType, DType::F32>{}, nullptr);
    case DType::F16: return f(std::integral_constant<DType, DType::F16>{}, nullptr);
    case DType::BF16: return f(std::integral_constant<DType, DType::BF16>{}, nullptr);
    default: return f(std::integral_constant<DType, DType::I8>{}, scale);
  }
}

// A W-wide panel (B's columns, W = NR, or A's rows, W = MR). `contiguous`: the W lanes are consecutive in memory
// (B not transposed, A transposed); otherwise each lane is its own row of length kc. `rest` packs the K tail of
// the strided case (and partial panels of it) with the portable packer of the same contract.
template <int W>
void pack_panel(const void* p, DType dt, int64_t ld, bool contiguous, const float* scale, int64_t kc, int n,
                float* dst, void (*rest)(const void*, DType, int64_t, const float*, int64_t, int, float*)) {
  if (contiguous)
    return with_packable_dtype(dt, scale,
                               [&](auto t, const float* s) { pack_contiguous<W>(p, t(), ld, s, kc, n, dst); });
  int64_t done = 0;
  if (n == W)
    done = with_packable_dtype(dt, scale,
                               [&](auto t, const float* s) { return pack_strided<W>(p, t(), ld, s, kc, dst); });
  if (done < kc) rest(static_cast<const char*>(p) + done * elem_size(dt), dt, ld, scale, kc - done, n, dst + done * W);
}

}  // namespace

void pack_b_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                   float* dst) {
  if (!packable(dt)) return pack_b_portable<NR>(p, dt, ld, trans, scale, kc, nr, dst);
  pack_panel<NR>(p, dt, ld, !trans, scale, kc, nr, dst,
                 [](const void* q, DType t, int64_t l, const float* s, int64_t k, int n, float* d) {
                   pack_b_portable<NR>(q, t, l, true, s, k, n, d);
                 });
}

void pack_a_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                   float* dst) {
  if (!packable(dt)) return pack_a_portable<MR>(p, dt, ld, trans, scale, mr, kc, dst);
  pack_panel<MR>(p, dt, ld, trans, scale, kc, mr, dst,
                 [](const void* q, DType t, int64_t l, const float* s, int64_t k, int n, float* d) {
                   pack_a_portable<MR>(q, t, l, false, s, n, k, d);
                 });
}

// ---- bfloat16 pair packing (Precision::Bf16 with AVX512-BF16) ------------------------------------------------------
// pack_a/pack_b_avx512 followed by to_bf16_pairs_avx512, in one pass and with the same values (x, times its scale
// in float32, rounded to nearest even): slot p*W + j = bf16(x(2p, j)) | bf16(x(2p + 1, j)) << 16, x(kc, j) = 0,
// lanes >= n zero.

namespace {

// Pairs (lo_j, hi_j) of two 16-lane vectors as 16 32-bit slots.
EGOPD_TARGET_BF16 __attribute__((always_inline)) inline __m512i bf16_pairs16(__m512 lo, __m512 hi) {
  const __m512i interleave = _mm512_set_epi16(31, 15, 30, 14, 29, 13, 28, 12, 27, 11, 26, 10, 25, 9, 24, 8, 23, 7, 22,
                                              6, 21, 5, 20, 4, 19, 3, 18, 2, 17, 1, 16, 0);
  return _mm512_permutexvar_epi16(interleave, (__m512i)_mm512_cvtne2ps_pbh(hi, lo));
}

template <int W, DType dt>
EGOPD_TARGET_BF16 __attribute__((always_inline)) inline void pack_bf16_contiguous(const void* p, int64_t ld,
                                                                                  const float* scale, int64_t kc,
                                                                                  int n, uint32_t* dst) {
  constexpr int kChunks = (W + 15) / 16;
  const int64_t es = elem_size(dt);
  __mmask16 in[kChunks];
  __m512 s[kChunks];
  for (int q = 0; q < kChunks; ++q) {
    in[q] = lanes(n - 16 * q);
    s[q] = scale ? _mm512_maskz_loadu_ps(in[q], scale + 16 * q) : _mm512_set1_ps(1.0f);
  }
  for (int64_t pr = 0; 2 * pr < kc; ++pr) {
    _mm_prefetch(static_cast<const char*>(p) + (2 * pr * ld + W) * es, _MM_HINT_T1);
    _mm_prefetch(static_cast<const char*>(p) + ((2 * pr + 1) * ld + W) * es, _MM_HINT_T1);
    for (int q = 0; q < kChunks; ++q) {
      __m512 lo = load16(p, dt, 2 * pr * ld + 16 * q, in[q]), hi = _mm512_setzero_ps();
      if (2 * pr + 1 < kc) hi = load16(p, dt, (2 * pr + 1) * ld + 16 * q, in[q]);
      if (scale) lo = _mm512_mul_ps(lo, s[q]), hi = _mm512_mul_ps(hi, s[q]);
      _mm512_mask_storeu_epi32(dst + pr * W + 16 * q, lanes(W - 16 * q), bf16_pairs16(lo, hi));
    }
  }
}

// Each lane its own row: 16 k of a lane become its 8 slots, and 8 lanes' slots are transposed 8 x 8.
template <int W, DType dt>
EGOPD_TARGET_BF16 __attribute__((always_inline)) inline void pack_bf16_strided(const void* p, int64_t ld,
                                                                               const float* scale, int64_t kc, int n,
                                                                               uint32_t* dst) {
  const int64_t es = elem_size(dt);
  const char* base = static_cast<const char*>(p);
  for (int64_t k = 0; k < kc; k += 16) {
    const __mmask16 m = lanes(int(std::min<int64_t>(16, kc - k)));
    const int slot_rows = int(std::min<int64_t>(16, kc - k) + 1) / 2;
    for (int g = 0; g < W; g += 8) {
      __m256 r[8];
      for (int j = 0; j < 8; ++j) {
        const int lane = g + j;
        if (lane >= n || lane >= W) {
          r[j] = _mm256_setzero_ps();
          continue;
        }
        // Each lane is a stream of its own: fetch two steps ahead, and the next panel's row into L2.
        _mm_prefetch(base + (lane * ld + k + 32) * es, _MM_HINT_T0);
        _mm_prefetch(base + ((lane + W) * ld + k) * es, _MM_HINT_T1);
        __m512 v = load16(p, dt, lane * ld + k, m);
        if (scale) v = _mm512_mul_ps(v, _mm512_set1_ps(scale[lane]));
        r[j] = _mm256_castsi256_ps((__m256i)_mm512_cvtneps_pbh(v));
      }
      transpose8(r);
      const __mmask8 wm = __mmask8(W - g >= 8 ? 0xff : (1u << (W - g)) - 1u);
      for (int q = 0; q < slot_rows; ++q)
        _mm256_mask_storeu_ps(reinterpret_cast<float*>(dst + (k / 2 + q) * W + g), wm, r[q]);
    }
  }
}

template <int W, DType dt>
EGOPD_TARGET_BF16 void pack_bf16(const void* p, int64_t ld, bool contiguous, const float* scale, int64_t kc, int n,
                                 float* dst) {
  uint32_t* out = reinterpret_cast<uint32_t*>(dst);
  if (contiguous) pack_bf16_contiguous<W, dt>(p, ld, scale, kc, n, out);
  else pack_bf16_strided<W, dt>(p, ld, scale, kc, n, out);
}

template <int W>
void pack_bf16_panel(const void* p, DType dt, int64_t ld, bool contiguous, const float* scale, int64_t kc, int n,
                     float* dst) {
  with_packable_dtype(dt, scale, [&](auto t, const float* s) { pack_bf16<W, t()>(p, ld, contiguous, s, kc, n, dst); });
}

}  // namespace

void pack_b_bf16_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                        float* dst) {
  if (!packable(dt)) {
    pack_b_portable<NR>(p, dt, ld, trans, scale, kc, nr, dst);
    return to_bf16_pairs_avx512(dst, NR, kc);
  }
  pack_bf16_panel<NR>(p, dt, ld, !trans, scale, kc, nr, dst);
}

void pack_a_bf16_avx512(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                        float* dst) {
  if (!packable(dt)) {
    pack_a_portable<MR>(p, dt, ld, trans, scale, mr, kc, dst);
    return to_bf16_pairs_avx512(dst, MR, kc);
  }
  pack_bf16_panel<MR>(p, dt, ld, trans, scale, kc, mr, dst);
}

void pack_b_temporal_wino_avx512(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                                 int64_t panel_floats) {
  temporal_wino_pack<NR>(m, in, ld, kc, nr, dst, panel_floats);
}

void temporal_wino_output_avx512(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                                 const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                                 int64_t row_stride) {
  temporal_wino_out<NR>(m, prod, prod_stride, frames, mr, nr, bias, accumulate, dst, frame_stride, row_stride);
}

}  // namespace egopd::gemm_detail
