#pragma once
// FNV-1a, 64-bit: a small stable hash for cache keys and per-name seeds (stable across builds and hosts; not for
// security or hash tables under attack).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>

namespace egopd {

constexpr uint64_t kFnv1aBasis = 1469598103934665603ull;

// Hash of `size` bytes at `data`, continuing from `h` (chain calls to hash several pieces).
inline uint64_t fnv1a(const void* data, size_t size, uint64_t h = kFnv1aBasis) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}
inline uint64_t fnv1a(const std::string& s, uint64_t h = kFnv1aBasis) { return fnv1a(s.data(), s.size(), h); }

// Sixteen lower-case hex digits.
inline std::string hex16(uint64_t h) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
  return hex;
}

}  // namespace egopd
