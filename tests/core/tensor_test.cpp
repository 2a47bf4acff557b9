// Tensor, Arena and the dtype conversions.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "core/dtype.h"
#include "core/error.h"
#include "core/tensor.h"
#include "core/threading.h"

namespace egopd {
namespace {

// binary16 value computed from its fields with ldexp (independent of the bit-twiddling under test)
double half_reference(uint16_t h) {
  const int sign = (h >> 15) & 1, exp = (h >> 10) & 0x1f, man = h & 0x3ff;
  double v;
  if (exp == 0) v = std::ldexp(double(man), -24);
  else if (exp == 31) v = man ? NAN : INFINITY;
  else v = std::ldexp(double(1024 + man), exp - 25);
  return sign ? -v : v;
}

TEST(Dtype, HalfToFloatExhaustive) {
  for (uint32_t h = 0; h < 65536; ++h) {
    const float f = half_to_float(uint16_t(h));
    const double r = half_reference(uint16_t(h));
    if (std::isnan(r)) {
      EXPECT_TRUE(std::isnan(f)) << h;
    } else {
      ASSERT_EQ(double(f), r) << h;
      ASSERT_EQ(std::signbit(f), std::signbit(r)) << h;
    }
  }
}

// Against the definition on a sweep of floats across the finite halves' range (normal and subnormal, both signs) and
// every midpoint between neighbouring halves: no neighbouring half is nearer, and a tie gives the even one.
TEST(Dtype, FloatToHalfIsTheNearestHalf) {
  const auto check = [](float f) {
    const uint16_t h = float_to_half(f);
    const uint16_t mag = h & 0x7fffu;
    ASSERT_LE(mag, 0x7bffu) << f;  // finite below 65520
    ASSERT_EQ(h >> 15, std::signbit(f) ? 1u : 0u) << f;
    const double a = std::fabs(double(f)), d = std::fabs(a - double(half_to_float(mag)));
    for (int step : {-1, 1}) {
      if ((mag == 0 && step < 0) || (mag == 0x7bff && step > 0)) continue;
      const double dn = std::fabs(a - double(half_to_float(uint16_t(mag + step))));
      ASSERT_LE(d, dn) << f;
      if (d == dn) {
        ASSERT_EQ(mag & 1u, 0u) << "tie of " << f;
      }
    }
  };
  for (uint32_t bits = 0; bits < 0x477fe000u; bits += 997) {
    float f;
    std::memcpy(&f, &bits, 4);
    check(f);
    check(-f);
  }
  for (uint16_t m = 0; m < 0x7bff; ++m) {  // midpoints, exact in float32
    const float mid = float((double(half_to_float(m)) + double(half_to_float(uint16_t(m + 1)))) / 2);
    check(mid);
    check(-mid);
  }
}

// The batch conversion (F16C where the CPU has it) gives float_to_half's halves: blocks of 8 and tails, NaNs (with
// payloads, beside finite values), infinities, overflow, ties and subnormals.
TEST(Dtype, FloatsToHalvesMatchesTheScalarConversion) {
  std::mt19937 rng(5);
  std::vector<float> v;
  for (int i = 0; i < 4000; ++i) {
    const uint32_t bits = uint32_t(rng());
    float f;
    std::memcpy(&f, &bits, 4);
    v.push_back(f);  // any bit pattern: NaNs with payloads, inf, huge, tiny
    v.push_back(std::ldexp(float(int(rng() % 2001) - 1000) / 1000.0f, int(rng() % 40) - 26));
  }
  for (float f : {65519.0f, 65520.0f, 1.0f + std::ldexp(1.0f, -11), std::ldexp(1.0f, -25), std::ldexp(1.5f, -25)})
    v.push_back(f);
  for (size_t n : {size_t(0), size_t(1), size_t(7), size_t(8), size_t(9), size_t(17), v.size()}) {
    std::vector<uint16_t> got(n + 1, 0xabcd);
    floats_to_halves(v.data(), got.data(), n);
    for (size_t i = 0; i < n; ++i) ASSERT_EQ(got[i], float_to_half(v[i])) << "n " << n << " i " << i << " " << v[i];
    ASSERT_EQ(got[n], 0xabcd) << n;  // nothing written past n
  }
}

TEST(Dtype, FloatToHalfRoundsToNearestEven) {
  for (uint32_t h = 0; h < 65536; ++h) {  // every half survives the round trip
    if (std::isnan(half_reference(uint16_t(h)))) continue;
    ASSERT_EQ(float_to_half(half_to_float(uint16_t(h))), h) << h;
  }
  // halfway between 1 and 1+2^-10 rounds to even (1); just above rounds up
  EXPECT_EQ(half_to_float(float_to_half(1.0f + std::ldexp(1.0f, -11))), 1.0f);
  EXPECT_EQ(half_to_float(float_to_half(1.0f + std::ldexp(1.0f, -11) + std::ldexp(1.0f, -20))),
            1.0f + std::ldexp(1.0f, -10));
  EXPECT_TRUE(std::isinf(half_to_float(float_to_half(65520.0f))));
  EXPECT_EQ(half_to_float(float_to_half(65519.0f)), 65504.0f);
  EXPECT_EQ(half_to_float(float_to_half(std::ldexp(1.0f, -25))), 0.0f);  // tie to even (0)
  EXPECT_EQ(half_to_float(float_to_half(std::ldexp(1.5f, -25))), std::ldexp(1.0f, -24));
  EXPECT_TRUE(std::isnan(half_to_float(float_to_half(NAN))));
}

TEST(Dtype, Bfloat16) {
  EXPECT_EQ(bf16_to_float(float_to_bf16(1.0f)), 1.0f);
  // 1 + 2^-8 is halfway between 1 and 1 + 2^-7: ties to even
  EXPECT_EQ(bf16_to_float(float_to_bf16(1.0f + std::ldexp(1.0f, -8))), 1.0f);
  EXPECT_EQ(bf16_to_float(float_to_bf16(1.0f + 3 * std::ldexp(1.0f, -8))), 1.0f + std::ldexp(1.0f, -6));
  EXPECT_TRUE(std::isnan(bf16_to_float(float_to_bf16(NAN))));
  uint16_t b[2] = {0x3f80, 0xc000};
  float out[2];
  convert_to_f32(DType::BF16, b, out, 2);
  EXPECT_EQ(out[0], 1.0f);
  EXPECT_EQ(out[1], -2.0f);
  EXPECT_THROW(convert_to_f32(DType::I64, b, out, 1), Error);
}

TEST(Tensor, ShapesViewsAndClones) {
  Tensor t = Tensor::from({2, 3}, {0, 1, 2, 3, 4, 5});
  EXPECT_EQ(t.shape().str(), "[2,3]");
  EXPECT_EQ(t.dim(-1), 3);
  Tensor r = t.reshaped({3, 2});
  r[0] = 9;
  EXPECT_EQ(t[0], 9);  // shallow
  Tensor c = t.clone();
  c[1] = 7;
  EXPECT_EQ(t[1], 1);  // deep
  EXPECT_EQ(reinterpret_cast<uintptr_t>(t.data()) % 64, 0u);
  EXPECT_THROW(t.reshaped({4, 2}), Error);
  EXPECT_THROW(Shape({1, 2, 3, 4, 5, 6, 7}), Error);
  Tensor six({1, 2, 1, 2, 1, 2});
  EXPECT_EQ(six.numel(), 8);
}

TEST(Arena, ReusesReleasedMemoryAndGrows) {
  Arena a(64);
  const size_t m = a.mark();
  Tensor x = a.take({10});
  Tensor y = a.take({100});  // does not fit the first chunk: a new chunk, x stays valid
  x[9] = 1.0f;
  y[99] = 2.0f;
  EXPECT_EQ(x[9], 1.0f);
  EXPECT_EQ(reinterpret_cast<uintptr_t>(y.data()) % 64, 0u);
  a.release(m);
  Tensor z = a.take({10});
  EXPECT_EQ(z.data(), x.data());  // the same block again
  EXPECT_GE(a.peak_bytes(), 110 * sizeof(float));
  EXPECT_THROW(a.release(a.mark() + 16), Error);
}

TEST(Arena, ShrinksToOneChunkOfItsPeakThatTheSamePassFits) {
  Arena a(64);
  const auto pass = [&] {
    Tensor x = a.take({10});   // 16 floats after alignment
    Tensor y = a.take({100});  // 112: skips the first chunk's tail on the first pass
    const size_t m = a.mark();
    Tensor z = a.take({33});   // 48
    a.release(m);
    Tensor w = a.take({20});  // 32, where z was
    x[0] = y[0] = w[0] = 1.0f;
    a.reset();
  };
  pass();
  EXPECT_GT(a.capacity_bytes(), a.peak_bytes());  // two chunks with growth slack
  const size_t peak = a.peak_bytes();
  a.shrink_to_peak();
  EXPECT_EQ(a.capacity_bytes(), peak);
  pass();  // the same requests fit the single chunk: it does not grow
  EXPECT_EQ(a.capacity_bytes(), peak);
  Tensor t = a.take({1});
  EXPECT_THROW(a.shrink_to_peak(), Error);  // not while something is taken
}

TEST(Threads, SettingAndDefault) {
  set_num_threads(1);
  EXPECT_EQ(num_threads(), 1);
  set_num_threads(0);
  EXPECT_GE(num_threads(), 1);
  EXPECT_GE(physical_cores(), 1);
}

}  // namespace
}  // namespace egopd
