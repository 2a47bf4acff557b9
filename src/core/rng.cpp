// Compiled with -ffp-contract=off: every float operation below is one IEEE rounding, and the fused
// multiply-adds that torch's AVX2 build performs are spelled out with std::fmaf.
#include "core/rng.h"

#include <bit>
#include <cmath>

namespace egopd {

// ---- MT19937 ----

void Mt19937::seed_with(uint32_t seed) {
  st_[0] = seed;
  for (uint32_t i = 1; i < 624; ++i) st_[i] = 1812433253u * (st_[i - 1] ^ (st_[i - 1] >> 30)) + i;
  idx_ = 624;
}

void Mt19937::twist() {
  for (int i = 0; i < 624; ++i) {
    const uint32_t y = (st_[i] & 0x80000000u) | (st_[(i + 1) % 624] & 0x7fffffffu);
    st_[i] = st_[(i + 397) % 624] ^ (y >> 1) ^ ((y & 1u) ? 0x9908b0dfu : 0u);
  }
  idx_ = 0;
}

uint32_t Mt19937::next() {
  if (idx_ >= 624) twist();
  uint32_t y = st_[idx_++];
  y ^= y >> 11;
  y ^= (y << 7) & 0x9d2c5680u;
  y ^= (y << 15) & 0xefc60000u;
  y ^= y >> 18;
  return y;
}

// ---- float32 Cephes polynomials as in torch's avx_mathfun.h (with the compiler's FMA contractions) ----
namespace {

// Natural log for x in (0, 1].
float cephes_log(float x) {
  const uint32_t bits = std::bit_cast<uint32_t>(x);
  float e = float(int32_t((bits >> 23) & 0xffu) - 126);
  const float m = std::bit_cast<float>((bits & 0x807fffffu) | 0x3f000000u);  // exponent 126: m in [0.5, 1)
  if (m < 0.707106781186547524f) {
    e = e - 1.0f;
    x = (m - 1.0f) + m;
  } else {
    x = m - 1.0f;
  }
  const float z = x * x;
  static constexpr float p[9] = {7.0376836292e-2f,  -1.1514610310e-1f, 1.1676998740e-1f,
                                 -1.2420140846e-1f, 1.4249322787e-1f,  -1.6668057665e-1f,
                                 2.0000714765e-1f,  -2.4999993993e-1f, 3.3333331174e-1f};
  float y = p[0];
  for (int k = 1; k <= 8; ++k) y = std::fmaf(y, x, p[k]);
  y = y * x;
  const float eq1 = e * -2.12194440e-4f;
  y = std::fmaf(y, z, eq1);
  y = y - 0.5f * z;
  x = x + y;
  return std::fmaf(e, 0.693359375f, x);
}

// sin and cos for theta in [0, 2*pi).
void cephes_sincos(float theta, float* sn, float* cs) {
  const float scaled = theta * 1.27323954473516f;
  int32_t j = int32_t(scaled);  // truncation
  j = (j + 1) & ~1;
  const float y = float(j);
  float a = std::fmaf(y, -0.78515625f, theta);
  a = std::fmaf(y, -2.4187564849853515625e-4f, a);
  a = std::fmaf(y, -3.77489497744594108e-8f, a);
  const float z = a * a;

  float c = std::fmaf(2.443315711809948e-5f, z, -1.388731625493765e-3f);
  c = std::fmaf(c, z, 4.166664568298827e-2f);
  c = c * z;
  c = std::fmaf(c, z, -(0.5f * z));
  c = c + 1.0f;

  float s = std::fmaf(-1.9515295891e-4f, z, 8.3321608736e-3f);
  s = std::fmaf(s, z, -1.6666654611e-1f);
  s = s * z;
  s = std::fmaf(s, a, a);

  float sin_v = s, cos_v = c;
  if ((j & 2) != 0) {
    sin_v = c;
    cos_v = s;
  }
  if ((j & 4) != 0) sin_v = -sin_v;
  if (((j - 2) & 4) == 0) cos_v = -cos_v;
  *sn = sin_v;
  *cs = cos_v;
}

// Box-Muller on one block of 16 uniforms: pairs (b[j], b[j+8]) -> two normals, in place.
void normal_fill_16(float* b) {
  for (int j = 0; j < 8; ++j) {
    const float u1 = 1.0f - b[j];
    const float u2 = b[j + 8];
    const float r = std::sqrt(-2.0f * cephes_log(u1));
    const float theta = 6.2831854820251465f * u2;
    float sn, cs;
    cephes_sincos(theta, &sn, &cs);
    // torch stores fma(n, std, mean) with std = 1, mean = 0 (turns -0 into +0).
    b[j] = std::fmaf(r * cs, 1.0f, 0.0f);
    b[j + 8] = std::fmaf(r * sn, 1.0f, 0.0f);
  }
}

}  // namespace

// ---- generator ----

void TorchGenerator::manual_seed(uint64_t seed) {
  engine_.seed_with(uint32_t(seed & 0xffffffffu));
  has_cached_normal_ = false;
  cached_normal_ = 0;
}

float TorchGenerator::uniform_float() { return float(next_u32() & 0xffffffu) * 0x1p-24f; }

double TorchGenerator::uniform_double() {
  const uint64_t hi = next_u32();
  const uint64_t lo = next_u32();
  return double(((hi << 32) | lo) & ((uint64_t(1) << 53) - 1)) * 0x1p-53;
}

float TorchGenerator::scalar_normal() {
  if (has_cached_normal_) {
    has_cached_normal_ = false;
    return float(cached_normal_);
  }
  const double u1 = uniform_double();
  const double u2 = uniform_double();
  const double r = std::sqrt(-2.0 * std::log(1.0 - u2));
  const double theta = 2.0 * 3.14159265358979323846 * u1;
  cached_normal_ = r * std::sin(theta);
  has_cached_normal_ = true;
  return float(r * std::cos(theta));
}

void TorchGenerator::randn(float* out, int64_t n) {
  if (n <= 0) return;
  if (n < 16) {
    for (int64_t i = 0; i < n; ++i) out[i] = scalar_normal();
    return;
  }
  for (int64_t i = 0; i < n; ++i) out[i] = uniform_float();
  for (int64_t i = 0; i + 16 <= n; i += 16) normal_fill_16(out + i);
  if (n % 16 != 0) {
    // torch redraws the last 16 entries (overwriting already transformed ones) and transforms them again.
    float* tail = out + n - 16;
    for (int i = 0; i < 16; ++i) tail[i] = uniform_float();
    normal_fill_16(tail);
  }
}

Tensor TorchGenerator::randn(const Shape& shape) {
  Tensor t(shape);
  randn(t.data(), t.numel());
  return t;
}

}  // namespace egopd
