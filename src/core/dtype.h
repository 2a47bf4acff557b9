#pragma once
// Storage dtypes of weights and tensors, and exact scalar conversions to float32.
#include <cstdint>
#include <cstring>
#include <string>

namespace egopd {

enum class DType : uint8_t { F32, F16, BF16, I64, I32, I8, U8, BOOL, F64 };

size_t dtype_size(DType t);
const char* dtype_name(DType t);             // safetensors spelling: "F32", "F16", ...
bool dtype_from_name(const std::string& s, DType* out);
inline bool is_float_weight(DType t) { return t == DType::F32 || t == DType::F16 || t == DType::BF16; }

// IEEE-754 binary16 -> binary32, exact (subnormals, inf, NaN).
inline float half_to_float(uint16_t h) {
  uint32_t sign = uint32_t(h & 0x8000u) << 16;
  uint32_t exp = (h >> 10) & 0x1f;
  uint32_t man = h & 0x3ffu;
  uint32_t bits;
  if (exp == 0) {
    if (man == 0) {
      bits = sign;
    } else {  // subnormal: normalise
      int e = -1;
      do {
        ++e;
        man <<= 1;
      } while ((man & 0x400u) == 0);
      bits = sign | uint32_t(127 - 15 - e) << 23 | (man & 0x3ffu) << 13;
    }
  } else if (exp == 31) {
    bits = sign | 0x7f800000u | man << 13;
  } else {
    bits = sign | (exp + 112) << 23 | man << 13;
  }
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

// binary32 -> binary16, round to nearest even (used by the converter and by tests).
uint16_t float_to_half(float f);
// float_to_half of n values (F16C where the CPU has it, the same halves).
void floats_to_halves(const float* src, uint16_t* dst, size_t n);

inline float bf16_to_float(uint16_t b) {
  uint32_t bits = uint32_t(b) << 16;
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}

// binary32 -> bfloat16, round to nearest even (NaN stays NaN).
// A select rather than a branch, so that loops over it vectorise.
inline uint16_t float_to_bf16(float f) {
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  const uint32_t nan = (bits >> 16) | 0x40u, rounded = (bits + 0x7fffu + ((bits >> 16) & 1u)) >> 16;
  return uint16_t((bits & 0x7fffffffu) > 0x7f800000u ? nan : rounded);
}

// f rounded to the nearest bfloat16 (ties to even), as a float32.
inline float rounded_to_bf16(float f) { return bf16_to_float(float_to_bf16(f)); }

// Convert n elements of a float-typed buffer (F32/F16/BF16) to float32.
void convert_to_f32(DType t, const void* src, float* dst, size_t n);

}  // namespace egopd
