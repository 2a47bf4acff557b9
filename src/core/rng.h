#pragma once
// Torch-compatible CPU random generator: reproduces
//   g = torch.Generator().manual_seed(S); torch.randn(shape, generator=g)
// bit for bit (float32, PyTorch's x86-64 AVX2 build), so a seeded run draws the same noise as the reference.
// Engine: 32-bit MT19937. randn of n < 16 elements uses scalar double Box-Muller with a cached second value;
// n >= 16 fills 16 elements at a time with float32 Box-Muller on Cephes log/sincos polynomials.
#include <cstdint>

#include "core/tensor.h"

namespace egopd {

class Mt19937 {
 public:
  explicit Mt19937(uint32_t seed = 5489u) { seed_with(seed); }
  void seed_with(uint32_t seed);
  uint32_t next();

 private:
  void twist();
  uint32_t st_[624];
  int idx_ = 624;
};

class TorchGenerator {
 public:
  static constexpr uint64_t kDefaultSeed = 67280421310721ull;  // torch's default_rng_seed_val

  explicit TorchGenerator(uint64_t seed = kDefaultSeed) { manual_seed(seed); }
  // Only the low 32 bits matter (a negative torch seed is its two's complement). Clears the cached normal.
  void manual_seed(uint64_t seed);

  uint32_t next_u32() { return engine_.next(); }
  float uniform_float();    // (w & 0xFFFFFF) * 2^-24
  double uniform_double();  // 53 bits of two words, first word high

  // One torch.randn call over n contiguous elements (row-major over the whole shape).
  void randn(float* out, int64_t n);
  Tensor randn(const Shape& shape);

 private:
  float scalar_normal();  // n < 16 path: one element, using / refilling the cached value
  Mt19937 engine_;
  bool has_cached_normal_ = false;
  double cached_normal_ = 0;
};

}  // namespace egopd
