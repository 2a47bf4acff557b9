#pragma once
// The AVX-512 intrinsics of this folder in portable code, for a build configured with -DEGOPD_EMULATE_AVX512=ON:
// SIMDe's implementations (its native aliases map _mm512_* to them), and below, in SIMDe's style, the ones the
// Debian SIMDe (0.7.4) lacks. They follow the instruction set reference's definitions (masked loads read only
// the selected elements; float -> bfloat16 rounds to nearest even, makes NaNs quiet and flushes denormal inputs to
// zero; float -> int32 out of range gives 0x80000000). Such a build runs the avx512 path on any AVX2 CPU; it is a
// test build (it checks numbers, not speed): the files are compiled for AVX2 + FMA + F16C and the pragmas of the
// native build are left out. Include ONLY through avx512/isa.h.
#include <immintrin.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#define SIMDE_ENABLE_NATIVE_ALIASES
#include <simde/x86/avx512.h>

namespace egopd::avx512_emulated {

// Whole registers to and from arrays of lanes.
template <class T, class V>
inline void lanes_of(const V& v, T* out) {
  std::memcpy(out, &v, sizeof(V));
}
template <class V, class T>
inline V from_lanes(const T* in) {
  V v;
  std::memcpy(&v, in, sizeof(V));
  return v;
}

// The register R whose N lanes of To are f of the N lanes of From in v.
template <class R, class To, class From, int N, class V, class F>
inline R map_lanes(const V& v, F f) {
  From in[N];
  To out[N];
  lanes_of(v, in);
  for (int i = 0; i < N; ++i) out[i] = f(in[i]);
  return from_lanes<R>(out);
}

// The register R of lanes of T: p[i] where mask bit i is set (only those are read), else 0.
template <class R, class T>
inline R masked_load(uint64_t k, const void* p) {
  constexpr int N = sizeof(R) / sizeof(T);
  T v[N];
  for (int i = 0; i < N; ++i) v[i] = (k >> i) & 1 ? static_cast<const T*>(p)[i] : T(0);
  return from_lanes<R>(v);
}
// p[i] = lane i (of T) of the register a where mask bit i is set (only those are written).
template <class T, class V>
inline void masked_store(void* p, uint64_t k, const V& a) {
  constexpr int N = sizeof(V) / sizeof(T);
  T v[N];
  lanes_of(a, v);
  for (int i = 0; i < N; ++i)
    if ((k >> i) & 1) static_cast<T*>(p)[i] = v[i];
}

inline uint16_t to_bf16(float x) {
  uint32_t u;
  std::memcpy(&u, &x, 4);
  if ((u & 0x7f800000u) == 0) return uint16_t((u >> 16) & 0x8000u);  // zero or denormal: signed zero
  if ((u & 0x7f800000u) == 0x7f800000u && (u & 0x007fffffu)) return uint16_t((u >> 16) | 0x0040u);  // quiet NaN
  return uint16_t((u + 0x7fffu + ((u >> 16) & 1u)) >> 16);
}

inline simde__m512 mask_loadu_ps(simde__m512 src, simde__mmask16 k, const void* p) {
  return simde_mm512_mask_mov_ps(src, k, masked_load<simde__m512, float>(k, p));
}
inline __m256 extractf32x8_ps(simde__m512 a, int imm8) {
  float v[16];
  lanes_of(a, v);
  return from_lanes<__m256>(v + 8 * (imm8 & 1));
}
inline simde__m512i cvtepu16_epi32(__m256i a) {
  return map_lanes<simde__m512i, int32_t, uint16_t, 16>(a, [](uint16_t x) { return int32_t(x); });
}
inline simde__m512i cvtepi8_epi32(__m128i a) {
  return map_lanes<simde__m512i, int32_t, int8_t, 16>(a, [](int8_t x) { return int32_t(x); });
}
inline __m256i cvtepi32_epi16(simde__m512i a) {  // truncation
  return map_lanes<__m256i, int16_t, int32_t, 16>(a, [](int32_t x) { return int16_t(x); });
}
inline simde__m512 cvtepi32_ps(simde__m512i a) {
  return map_lanes<simde__m512, float, int32_t, 16>(a, [](int32_t x) { return float(x); });
}
inline simde__m512i cvtps_epi32(simde__m512 a) {
  return map_lanes<simde__m512i, int32_t, float, 16>(a, [](float x) {
    const float t = std::nearbyint(x);  // the default rounding: to nearest even
    return t >= -2147483648.0f && t < 2147483648.0f ? int32_t(t) : INT32_MIN;
  });
}
inline simde__m512d cvtps_pd(__m256 a) {
  return map_lanes<simde__m512d, double, float, 8>(a, [](float x) { return double(x); });
}
inline simde__m512 cvtph_ps(__m256i a) {  // F16C is native in these builds
  return simde_mm512_insertf32x8(simde_mm512_castps256_ps512(_mm256_cvtph_ps(_mm256_castsi256_si128(a))),
                                 _mm256_cvtph_ps(_mm256_extracti128_si256(a, 1)), 1);
}
// a rounded to a multiple of 2^-M (M = imm8 >> 4) by the mode in imm8's low bits (bit 2: MXCSR's, nearest even
// here). SIMDe 0.7.4 rounds to other steps.
inline simde__m512 roundscale_ps(simde__m512 a, int imm8) {
  float v[16];
  lanes_of(a, v);
  const int mode = imm8 & 4 ? 0 : imm8 & 3;
  const double step = std::ldexp(1.0, (imm8 >> 4) & 15);
  for (float& x : v) {
    if (!std::isfinite(x)) {
      x = x + 0.0f;  // inf stays, NaN made quiet
      continue;
    }
    const double y = double(x) * step;
    const double r = mode == 0   ? std::nearbyint(y)
                     : mode == 1 ? std::floor(y)
                     : mode == 2 ? std::ceil(y)
                                 : std::trunc(y);
    x = std::copysign(float(r / step), x);  // keeps -0 for negative inputs rounded to zero
  }
  return from_lanes<simde__m512>(v);
}
// a 2^floor(b), rounded once (SIMDe flushes a denormal a, and multiplies by 2^floor(b) computed alone, which
// underflows to 0 below 2^-149 where the product would not).
inline simde__m512 scalef_ps(simde__m512 a, simde__m512 b) {
  float va[16], vb[16], r[16];
  lanes_of(a, va);
  lanes_of(b, vb);
  for (int i = 0; i < 16; ++i) {
    if (std::isnan(va[i]) || std::isnan(vb[i])) r[i] = std::isnan(va[i]) ? va[i] : vb[i];
    else if (std::isinf(vb[i])) r[i] = vb[i] > 0 ? va[i] * INFINITY : va[i] * 0.0f;  // inf * 0, 0 * inf: NaN
    else r[i] = float(std::ldexp(double(va[i]), int(std::clamp(std::floor(vb[i]), -1000.0f, 1000.0f))));
  }
  return from_lanes<simde__m512>(r);
}
inline simde__m256bh cvtneps_pbh(simde__m512 a) {
  return map_lanes<simde__m256bh, uint16_t, float, 16>(a, to_bf16);
}
inline simde__m512bh cvtne2ps_pbh(simde__m512 a, simde__m512 b) {  // b's lanes in the low half, a's in the high
  float va[16], vb[16];
  uint16_t r[32];
  lanes_of(a, va);
  lanes_of(b, vb);
  for (int i = 0; i < 16; ++i) r[i] = to_bf16(vb[i]), r[16 + i] = to_bf16(va[i]);
  return from_lanes<simde__m512bh>(r);
}

}  // namespace egopd::avx512_emulated

#define _mm512_maskz_loadu_ps(k, p) egopd::avx512_emulated::masked_load<simde__m512, float>(k, p)
#define _mm512_mask_loadu_ps(s, k, p) egopd::avx512_emulated::mask_loadu_ps(s, k, p)
#define _mm_maskz_loadu_epi8(k, p) egopd::avx512_emulated::masked_load<__m128i, int8_t>(k, p)
#define _mm256_maskz_loadu_epi16(k, p) egopd::avx512_emulated::masked_load<__m256i, int16_t>(k, p)
#define _mm512_mask_storeu_ps(p, k, a) egopd::avx512_emulated::masked_store<float>(p, k, a)
#define _mm512_mask_storeu_epi32(p, k, a) egopd::avx512_emulated::masked_store<int32_t>(p, k, a)
#define _mm256_mask_storeu_ps(p, k, a) egopd::avx512_emulated::masked_store<float>(p, k, a)
// clang declares every intrinsic whatever the target (these two as macros, for their immediates): replaced here.
#undef _mm512_shuffle_f32x4
#undef _mm512_extractf32x8_ps
#define _mm512_shuffle_f32x4(a, b, imm8) simde_mm512_shuffle_f32x4(a, b, imm8)
#define _mm512_extractf32x8_ps(a, imm8) egopd::avx512_emulated::extractf32x8_ps(a, imm8)
#define _mm512_cvtepu16_epi32(a) egopd::avx512_emulated::cvtepu16_epi32(a)
#define _mm512_cvtepi8_epi32(a) egopd::avx512_emulated::cvtepi8_epi32(a)
#define _mm512_cvtepi32_epi16(a) egopd::avx512_emulated::cvtepi32_epi16(a)
#define _mm512_cvtepi32_ps(a) egopd::avx512_emulated::cvtepi32_ps(a)
#define _mm512_cvtps_epi32(a) egopd::avx512_emulated::cvtps_epi32(a)
#define _mm512_cvtps_pd(a) egopd::avx512_emulated::cvtps_pd(a)
#define _mm512_cvtph_ps(a) egopd::avx512_emulated::cvtph_ps(a)
#undef _mm512_roundscale_ps
#define _mm512_roundscale_ps(a, imm8) egopd::avx512_emulated::roundscale_ps(a, imm8)
#undef _mm512_scalef_ps
#define _mm512_scalef_ps(a, b) egopd::avx512_emulated::scalef_ps(a, b)
#define _mm512_cvtneps_pbh(a) egopd::avx512_emulated::cvtneps_pbh(a)
#define _mm512_cvtne2ps_pbh(a, b) egopd::avx512_emulated::cvtne2ps_pbh(a, b)
