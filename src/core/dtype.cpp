#include "core/dtype.h"

#include "core/cpu.h"
#include "core/error.h"

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace egopd {

size_t dtype_size(DType t) {
  switch (t) {
    case DType::F32: return 4;
    case DType::F16: return 2;
    case DType::BF16: return 2;
    case DType::I64: return 8;
    case DType::I32: return 4;
    case DType::I8: return 1;
    case DType::U8: return 1;
    case DType::BOOL: return 1;
    case DType::F64: return 8;
  }
  return 0;
}

const char* dtype_name(DType t) {
  switch (t) {
    case DType::F32: return "F32";
    case DType::F16: return "F16";
    case DType::BF16: return "BF16";
    case DType::I64: return "I64";
    case DType::I32: return "I32";
    case DType::I8: return "I8";
    case DType::U8: return "U8";
    case DType::BOOL: return "BOOL";
    case DType::F64: return "F64";
  }
  return "?";
}

bool dtype_from_name(const std::string& s, DType* out) {
  static const struct { const char* n; DType t; } table[] = {
      {"F32", DType::F32}, {"F16", DType::F16}, {"BF16", DType::BF16}, {"I64", DType::I64}, {"I32", DType::I32},
      {"I8", DType::I8},   {"U8", DType::U8},   {"BOOL", DType::BOOL}, {"F64", DType::F64}};
  for (const auto& e : table) {
    if (s == e.n) {
      *out = e.t;
      return true;
    }
  }
  return false;
}

uint16_t float_to_half(float f) {
  uint32_t x;
  std::memcpy(&x, &f, 4);
  uint32_t sign = (x >> 16) & 0x8000u;
  uint32_t absx = x & 0x7fffffffu;
  if (absx > 0x7f800000u) return uint16_t(sign | 0x7e00u);  // NaN
  if (absx >= 0x477ff000u) return uint16_t(sign | 0x7c00u);  // rounds to inf (>= 65520)
  if (absx < 0x38800000u) {                                  // subnormal half or zero
    if (absx < 0x33000000u) return uint16_t(sign);           // < 2^-25 rounds to 0
    uint32_t e = absx >> 23;
    uint32_t m = (absx & 0x7fffffu) | 0x800000u;
    uint32_t shift = 126 - e;  // 14 + (113 - e) ... aligns to 2^-24 units
    uint32_t half_m = m >> (shift);
    uint32_t rem = m & ((1u << shift) - 1);
    uint32_t halfway = 1u << (shift - 1);
    half_m += rem + (half_m & 1) > halfway;  // above halfway, or at it with an odd result: up (to even)
    return uint16_t(sign | half_m);
  }
  uint32_t h = ((absx - 0x38000000u) >> 13);
  uint32_t rem = absx & 0x1fffu;
  // Without a branch: random mantissas mispredicted it every other value (weight conversion, synthetic weights).
  h += rem + (h & 1) > 0x1000u;
  return uint16_t(sign | h);
}

#if defined(__x86_64__)
namespace {
// vcvtps2ph rounds to nearest even as float_to_half does; only NaNs differ (it keeps their payload, float_to_half
// writes one quiet NaN), so a block of 8 with a NaN takes the scalar function. Returns the values converted.
__attribute__((target("avx,f16c"))) size_t floats_to_halves_f16c(const float* src, uint16_t* dst, size_t n) {
  size_t i = 0;
  for (; i + 8 <= n; i += 8) {
    const __m256 x = _mm256_loadu_ps(src + i);
    if (_mm256_movemask_ps(_mm256_cmp_ps(x, x, _CMP_UNORD_Q)) != 0) {
      for (size_t j = i; j < i + 8; ++j) dst[j] = float_to_half(src[j]);
      continue;
    }
    _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + i), _mm256_cvtps_ph(x, _MM_FROUND_TO_NEAREST_INT));
  }
  return i;
}
}  // namespace
#endif

void floats_to_halves(const float* src, uint16_t* dst, size_t n) {
  size_t i = 0;
#if defined(__x86_64__)
  if (cpu_info().avx2_fma_f16c) i = floats_to_halves_f16c(src, dst, n);
#endif
  for (; i < n; ++i) dst[i] = float_to_half(src[i]);
}

void convert_to_f32(DType t, const void* src, float* dst, size_t n) {
  switch (t) {
    // Stored data is only byte-aligned (a safetensors header length need not be a multiple of 8): every element is
    // read with memcpy, and an empty tensor (possibly without data) is never touched.
    case DType::F32:
      if (n > 0) std::memcpy(dst, src, n * 4);
      return;
    case DType::F16:
    case DType::BF16: {
      const auto* s = static_cast<const uint8_t*>(src);
      for (size_t i = 0; i < n; ++i) {
        uint16_t h;
        std::memcpy(&h, s + 2 * i, 2);
        dst[i] = t == DType::F16 ? half_to_float(h) : bf16_to_float(h);
      }
      return;
    }
    default:
      throw Error(std::string("cannot convert dtype ") + dtype_name(t) + " to float32");
  }
}

}  // namespace egopd
