#pragma once
// Double-precision references shared by the kernel tests.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/kernels/gemm.h"

namespace egopd::test {

constexpr double kU = 1.0 / 16777216.0;  // 2^-24: float32 unit roundoff

// v (a float32 value) rounded to bfloat16: what Precision::Bf16 multiplies.
inline double round_bf16(double v) { return rounded_to_bf16(float(v)); }

inline double act_ref(Act act, double x) {
  switch (act) {
    case Act::None: return x;
    case Act::SiLU: return x / (1.0 + std::exp(-x));
    case Act::GELU: return 0.5 * x * (1.0 + std::erf(x / std::sqrt(2.0)));
    case Act::QuickGELU: return x / (1.0 + std::exp(-1.702 * x));
  }
  return x;
}

// Runs the kernels of path p while in scope, then the path that was in use before.
struct KernelPathGuard {
  KernelPath before = kernel_path();
  explicit KernelPathGuard(KernelPath p) { set_kernel_path(p); }
  ~KernelPathGuard() { set_kernel_path(before); }
};

// Computes in precision p while in scope (set_precision), then in the precision that was in use before.
struct PrecisionGuard {
  Precision before = precision();
  explicit PrecisionGuard(Precision p) { set_precision(p); }
  ~PrecisionGuard() { set_precision(before); }
};
inline Precision precision_of(bool bf16, bool int8) {
  return int8 ? Precision::Int8 : bf16 ? Precision::Bf16 : Precision::Fp32;
}

// Every kernel path, for parameterised suites (paths the CPU lacks are skipped with a message).
inline const KernelPath kAllKernelPaths[] = {KernelPath::Portable, KernelPath::Avx2, KernelPath::Avx512,
                                            KernelPath::Neon};

// Base of the suites parameterised over kernel paths: each test runs on its path (skipped, with the reason, where
// this CPU lacks it), then the path in use before is restored. Instantiate with
// INSTANTIATE_TEST_SUITE_P(Paths, Suite, ::testing::ValuesIn(test::kAllKernelPaths), test::kernel_path_test_name).
class KernelPathTest : public ::testing::TestWithParam<KernelPath> {
 protected:
  void SetUp() override {
    if (!kernel_path_supported(GetParam())) GTEST_SKIP() << "this CPU lacks " << kernel_path_features(GetParam());
    guard_.emplace(GetParam());
  }
  void TearDown() override { guard_.reset(); }

 private:
  std::optional<KernelPathGuard> guard_;
};
inline std::string kernel_path_test_name(const ::testing::TestParamInfo<KernelPath>& i) {
  return kernel_path_name(i.param);
}

// Weights stored in a dtype, with their exact values for the reference.
// I8 weights carry one scale per output channel (each channel = `per_channel` consecutive elements).
struct StoredWeight {
  DType dtype;
  std::vector<float> f32;
  std::vector<uint16_t> h16;
  std::vector<int8_t> i8;
  std::vector<float> scale;
  std::vector<double> value;
  StoredWeight(size_t n, DType dt, std::mt19937& rng, size_t per_channel = 1)
      : dtype(dt), f32(n), h16(n), i8(n), value(n) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    if (dt == DType::I8)
      for (size_t o = 0; o < n / per_channel; ++o) scale.push_back(0.005f + 0.001f * float(o % 7));
    for (size_t i = 0; i < n; ++i) {
      const float v = u(rng);
      if (dt == DType::F16) h16[i] = float_to_half(v), value[i] = half_to_float(h16[i]);
      else if (dt == DType::BF16) h16[i] = float_to_bf16(v), value[i] = bf16_to_float(h16[i]);
      else if (dt == DType::I8) i8[i] = int8_t(std::lround(v * 127)), value[i] = float(i8[i]) * scale[i / per_channel];
      else f32[i] = v, value[i] = v;
    }
  }
  Operand operand(int64_t ld) const {
    const void* p = dtype == DType::F32 ? static_cast<const void*>(f32.data())
                    : dtype == DType::I8 ? static_cast<const void*>(i8.data())
                                         : static_cast<const void*>(h16.data());
    return Operand{p, dtype, ld, false, scale.empty() ? nullptr : scale.data()};
  }
};

inline std::vector<float> random_vec(size_t n, std::mt19937& rng) {
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (auto& x : v) x = u(rng);
  return v;
}

}  // namespace egopd::test
