// AVX2/FMA/F16C micro-kernel (6 x 16, 12 ymm accumulators) and packing with on-the-fly F16/BF16 conversion.
// Only reached through the avx2 and avx512 kernel paths; everything below the pragma is plain static code (no library inlines).
#include <cstdint>

#include "core/kernels/gemm_internal.h"

#pragma GCC target("avx2,fma,f16c")
#include <immintrin.h>

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

}  // namespace

void microkernel_avx2(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c, int64_t ldc,
                      int mr, int nr, const TileEpilogue& ep) {
  __m256 c00 = _mm256_setzero_ps(), c01 = _mm256_setzero_ps(), c10 = _mm256_setzero_ps(),
         c11 = _mm256_setzero_ps(), c20 = _mm256_setzero_ps(), c21 = _mm256_setzero_ps(),
         c30 = _mm256_setzero_ps(), c31 = _mm256_setzero_ps(), c40 = _mm256_setzero_ps(),
         c41 = _mm256_setzero_ps(), c50 = _mm256_setzero_ps(), c51 = _mm256_setzero_ps();
  if (ep.load_c || ep.add_after)  // the C tile is read after the loop: start fetching it now
    for (int i = 0; i < mr; ++i) {
      _mm_prefetch(reinterpret_cast<const char*>(c + i * ldc), _MM_HINT_T0);
      _mm_prefetch(reinterpret_cast<const char*>(c + i * ldc + 15), _MM_HINT_T0);
    }
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
  if (mr == MR && nr == NR) {
    store_row(c, c00, c01, 0, ep);
    store_row(c + ldc, c10, c11, 1, ep);
    store_row(c + 2 * ldc, c20, c21, 2, ep);
    store_row(c + 3 * ldc, c30, c31, 3, ep);
    store_row(c + 4 * ldc, c40, c41, 4, ep);
    store_row(c + 5 * ldc, c50, c51, 5, ep);
    return;
  }
  alignas(32) float sum[MR * NR];
  _mm256_store_ps(sum + 0 * NR, c00);
  _mm256_store_ps(sum + 0 * NR + 8, c01);
  _mm256_store_ps(sum + 1 * NR, c10);
  _mm256_store_ps(sum + 1 * NR + 8, c11);
  _mm256_store_ps(sum + 2 * NR, c20);
  _mm256_store_ps(sum + 2 * NR + 8, c21);
  _mm256_store_ps(sum + 3 * NR, c30);
  _mm256_store_ps(sum + 3 * NR + 8, c31);
  _mm256_store_ps(sum + 4 * NR, c40);
  _mm256_store_ps(sum + 4 * NR + 8, c41);
  _mm256_store_ps(sum + 5 * NR, c50);
  _mm256_store_ps(sum + 5 * NR + 8, c51);
  store_tile_scalar(sum, c, ldc, mr, nr, ep);
}

#undef EGOPD_FMA_ROW
#undef EGOPD_PREFETCH_B

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

}  // namespace egopd::gemm_detail
