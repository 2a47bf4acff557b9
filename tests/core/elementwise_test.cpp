// Element-wise kernels against double-precision references, on every kernel path.
#include "core/kernels/elementwise.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "core/cpu.h"
#include "core/kernel_reference.h"

namespace egopd {
namespace {


constexpr double kUlp = 1.1920928955078125e-07;  // 2^-23

// Relative error in units of 2^-23, with an absolute floor below which differences are ignored.
double ulps(float got, double ref, double abs_floor = 1e-37) {
  const double err = std::fabs(static_cast<double>(got) - ref);
  if (err <= abs_floor) return 0.0;
  return err / (std::max(std::fabs(ref), 1e-300) * kUlp);
}

// Double-precision references. GELU's and quick GELU's float recipes round x/sqrt2 and 1.702 x to float first; the
// references do the same, so only the erf / exp part is judged.
double erf_ref(float x) { return std::erf(static_cast<double>(x)); }
double gelu_ref(float x) {
  const float z = x * 0.70710678118654752f;
  return 0.5 * x * std::erfc(-static_cast<double>(z));
}
double silu_ref(float x) { return x / (1.0 + std::exp(-static_cast<double>(x))); }
double quick_gelu_ref(float x) { return x / (1.0 + std::exp(-static_cast<double>(1.702f * x))); }

std::vector<float> dense_inputs(double lo, double hi, int n) {
  std::vector<float> x;
  for (int i = 0; i <= n; ++i) x.push_back(static_cast<float>(lo + (hi - lo) * i / n));
  for (float t : {1e-30f, 1e-20f, 1e-10f, 1e-6f, 3e-4f, 1e-38f, 0.0f, 0.999999f, 1.0f, 1.000001f, 9.9f}) {
    x.push_back(t);
    x.push_back(-t);
  }
  return x;
}

// Floats after a span a kernel must not write (one vector of the widest path and more).
constexpr int64_t kGuard = 20;
constexpr float kSentinel = -12345.0f;

void expect_guard_intact(const std::vector<float>& v, int64_t n, float sentinel) {
  for (size_t i = n; i < v.size(); ++i) ASSERT_EQ(v[i], sentinel) << "written past the span at " << i;
}

// The in-place maps, their references and the accuracy the dense-range tests below establish.
struct MapCase {
  const char* name;
  void (*fn)(float*, int64_t);
  double (*ref)(float);
  double max_ulps, abs_floor;
};
const MapCase kMaps[] = {{"erf", erf_inplace, erf_ref, 3.0, 0.0},
                         {"gelu", gelu_inplace, gelu_ref, 8.0, 1e-36},
                         {"silu", silu_inplace, silu_ref, 4.0, 1e-36},
                         {"quick_gelu", quick_gelu_inplace, quick_gelu_ref, 4.0, 1e-36}};

// Every length around the vector widths (8 on avx2, 16 on avx512, 4 on neon): full blocks, tails of each size and
// nothing written after the span.
TEST(Elementwise, MapsOnShortSpansAndTails) {
  std::vector<int64_t> lengths;
  for (int64_t n = 1; n <= 49; ++n) lengths.push_back(n);
  for (int64_t n : {63, 64, 65, 100, 127, 129, 255}) lengths.push_back(n);
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (const MapCase& m : kMaps)
      for (int64_t n : lengths) {
        SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " " << m.name << " n=" << n);
        std::vector<float> x(n + kGuard, kSentinel);
        for (int64_t i = 0; i < n; ++i) x[i] = -6.0f + 12.0f * static_cast<float>((i * 37) % n) / n + 0.01f * i;
        const std::vector<float> in = x;
        m.fn(x.data(), n);
        for (int64_t i = 0; i < n; ++i)
          ASSERT_LE(ulps(x[i], m.ref(in[i]), m.abs_floor), m.max_ulps) << "i=" << i << " x=" << in[i];
        expect_guard_intact(x, n, kSentinel);
      }
  }
}

// The bits of each float (NaNs compared by their bits as well).
std::vector<uint32_t> bits_of(const std::vector<float>& v) {
  std::vector<uint32_t> b(v.size());
  std::memcpy(b.data(), v.data(), v.size() * sizeof(float));
  return b;
}

// The avx512 kernels evaluate the avx2 kernels' polynomials with the same operations per lane, so every result has
// the same bits, in full vectors and in tails (spans of 37 floats: 2 blocks of 16 + 5, 4 of 8 + 5).
TEST(Elementwise, Avx512BitIdenticalToAvx2) {
  if (!kernel_path_supported(KernelPath::Avx2) || !kernel_path_supported(KernelPath::Avx512))
    GTEST_SKIP() << "needs the avx2 and avx512 kernel paths";
  std::vector<float> in = dense_inputs(-100.0, 100.0, 200001);
  for (const auto& more : {dense_inputs(-88.8, -86.5, 20001), dense_inputs(86.5, 88.8, 20001),  // exp's limits
                           dense_inputs(-14.5, -12.5, 20001)})  // GELU's subnormal results
    in.insert(in.end(), more.begin(), more.end());
  for (float t : {1e-45f, 1e-40f, 3e-39f, INFINITY, NAN, 1e30f, 3.4e38f}) in.push_back(t), in.push_back(-t);
  const auto run = [&](KernelPath path, void (*fn)(float*, int64_t), int64_t span) {
    test::KernelPathGuard guard(path);
    const int64_t n = static_cast<int64_t>(in.size());
    std::vector<float> y = in;
    y.resize(n + kGuard, kSentinel);
    for (int64_t b = 0; b < n; b += span) fn(y.data() + b, std::min(span, n - b));
    expect_guard_intact(y, n, kSentinel);
    y.resize(n);
    return bits_of(y);
  };
  for (const MapCase& m : kMaps)
    for (int64_t span : {int64_t{37}, static_cast<int64_t>(in.size())}) {
      SCOPED_TRACE(testing::Message() << m.name << " span=" << span);
      const std::vector<uint32_t> a = run(KernelPath::Avx2, m.fn, span), b = run(KernelPath::Avx512, m.fn, span);
      for (size_t i = 0; i < in.size(); ++i) ASSERT_EQ(a[i], b[i]) << "x=" << in[i];
    }

  std::mt19937 rng(5);
  std::normal_distribution<float> nd(0.0f, 5.0f);
  for (const auto& shape : {std::pair<int64_t, int64_t>{7, 1}, {5, 15}, {5, 17}, {3, 37}, {64, 200}}) {
    const int64_t rows = shape.first, d = shape.second;  // variables, not bindings: the lambda below captures them
    SCOPED_TRACE(testing::Message() << "geglu rows=" << rows << " d=" << d);
    std::vector<float> p(rows * 2 * d);
    for (float& v : p) v = nd(rng);
    const auto run_geglu = [&](KernelPath path) {
      test::KernelPathGuard guard(path);
      std::vector<float> out(rows * d + kGuard, kSentinel);
      geglu(p.data(), rows, d, out.data());
      expect_guard_intact(out, rows * d, kSentinel);
      out.resize(rows * d);
      return bits_of(out);
    };
    EXPECT_EQ(run_geglu(KernelPath::Avx2), run_geglu(KernelPath::Avx512));
  }
}

TEST(Elementwise, ErfAccurateToFewUlpOverDenseRange) {
  const std::vector<float> in = dense_inputs(-10.0, 10.0, 400001);
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    SCOPED_TRACE(kernel_path_name(path));
    std::vector<float> y = in;
    erf_inplace(y.data(), static_cast<int64_t>(y.size()));
    double worst = 0.0;
    float worst_x = 0.0f;
    for (size_t i = 0; i < in.size(); ++i) {
      const double u = ulps(y[i], erf_ref(in[i]), 0.0);
      if (u > worst) worst = u, worst_x = in[i];
    }
    EXPECT_LE(worst, 3.0) << "at x=" << worst_x;
  }
}

TEST(Elementwise, GeluExactErfFormRelativeAccuracy) {
  const std::vector<float> in = dense_inputs(-14.0, 14.0, 280001);
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    SCOPED_TRACE(kernel_path_name(path));
    std::vector<float> y = in;
    gelu_inplace(y.data(), static_cast<int64_t>(y.size()));
    double worst = 0.0;
    float worst_x = 0.0f;
    for (size_t i = 0; i < in.size(); ++i) {
      const double u = ulps(y[i], gelu_ref(in[i]), 1e-36);
      if (u > worst) worst = u, worst_x = in[i];
    }
    EXPECT_LE(worst, 8.0) << "at x=" << worst_x;
  }
}

TEST(Elementwise, SiluAndQuickGelu) {
  const std::vector<float> in = dense_inputs(-95.0, 95.0, 190001);
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    SCOPED_TRACE(kernel_path_name(path));
    std::vector<float> s = in, q = in;
    silu_inplace(s.data(), static_cast<int64_t>(s.size()));
    quick_gelu_inplace(q.data(), static_cast<int64_t>(q.size()));
    double ws = 0.0, wq = 0.0;
    for (size_t i = 0; i < in.size(); ++i) {
      ws = std::max(ws, ulps(s[i], silu_ref(in[i]), 1e-36));
      wq = std::max(wq, ulps(q[i], quick_gelu_ref(in[i]), 1e-36));
    }
    EXPECT_LE(ws, 4.0);
    EXPECT_LE(wq, 4.0);
  }
}

TEST(Elementwise, GegluValueTimesGeluOfGate) {
  std::mt19937 rng(7);
  std::normal_distribution<float> nd(0.0f, 2.0f);
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (auto [rows, d] : {std::pair<int64_t, int64_t>{1, 1}, {3, 13}, {4, 15}, {2, 16}, {3, 17}, {2, 33}, {5, 37},
                           {2, 100}, {300, 200}}) {
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " rows=" << rows << " d=" << d);
      std::vector<float> p(rows * 2 * d), out(rows * d + kGuard, -7.0f);
      for (float& v : p) v = nd(rng);
      geglu(p.data(), rows, d, out.data());
      expect_guard_intact(out, rows * d, -7.0f);
      for (int64_t r = 0; r < rows; ++r)
        for (int64_t i = 0; i < d; ++i) {
          const double a = p[r * 2 * d + i], g = p[r * 2 * d + d + i];
          const double ref = a * 0.5 * g * std::erfc(-g / std::sqrt(2.0));
          ASSERT_NEAR(out[r * d + i], ref, 1e-6 * std::fabs(a * g) + 1e-30) << "r=" << r << " i=" << i;
        }
    }
  }
}

TEST(Elementwise, UpsampleNearest2x) {
  for (auto [planes, h, w] : {std::tuple<int64_t, int64_t, int64_t>{1, 1, 1}, {3, 1, 5}, {2, 3, 1}, {4, 5, 7}}) {
    std::vector<float> x(planes * h * w), y(planes * 4 * h * w, -1.0f);
    for (size_t i = 0; i < x.size(); ++i) x[i] = static_cast<float>(i) * 0.5f - 3.0f;
    upsample_nearest2x(x.data(), planes, h, w, y.data());
    for (int64_t p = 0; p < planes; ++p)
      for (int64_t i = 0; i < 2 * h; ++i)
        for (int64_t j = 0; j < 2 * w; ++j)
          ASSERT_EQ(y[(p * 2 * h + i) * 2 * w + j], x[(p * h + i / 2) * w + j / 2]);
  }
}

TEST(Elementwise, TimestepEmbeddingSpecCheckValues) {
  const float t = static_cast<float>(1.6377700567245483);
  std::vector<float> out(320);
  timestep_embedding(&t, 1, 320, out.data());
  EXPECT_NEAR(out[0], -0.0669236705, 2e-7);
  EXPECT_NEAR(out[1], 0.0246392153, 2e-7);
  EXPECT_NEAR(out[159], 1.0, 2e-7);
  EXPECT_NEAR(out[160], 0.99775809, 2e-7);
  EXPECT_NEAR(out[319], 0.0001734814, 2e-9);

  const float ids[3] = {4.0f, 127.0f, 0.02f};  // added_time_ids, each Sin(., 256)
  std::vector<float> aug(3 * 256);
  timestep_embedding(ids, 3, 256, aug.data());
  EXPECT_NEAR(aug[0], -0.653643608, 2e-7);
  EXPECT_NEAR(aug[128], -0.756802499, 2e-7);
  EXPECT_NEAR(aug[256], 0.232359096, 2e-6);  // arg 127 carries float rounding
  EXPECT_NEAR(aug[512], 0.999800026, 2e-7);
  EXPECT_NEAR(aug[640], 0.0199986659, 2e-8);
}

TEST(Elementwise, TimestepEmbeddingMatchesFormula) {
  const float t[2] = {0.0f, 3.25f};
  const int64_t dim = 6, half = 3;
  std::vector<float> out(2 * dim);
  timestep_embedding(t, 2, dim, out.data());
  for (int r = 0; r < 2; ++r)
    for (int i = 0; i < half; ++i) {
      const double arg = t[r] * std::exp(-std::log(10000.0) * i / half);
      EXPECT_NEAR(out[r * dim + i], std::cos(arg), 1e-6);
      EXPECT_NEAR(out[r * dim + half + i], std::sin(arg), 1e-6);
    }
  EXPECT_THROW(timestep_embedding(t, 1, 5, out.data()), std::exception);
}

TEST(Elementwise, BlendAndAdd) {
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (int64_t n : {1, 7, 15, 16, 17, 33, 37, 100003}) {
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " n=" << n);
      std::vector<float> x(n + kGuard, 5.0f), y(n + kGuard, kSentinel);
      for (int64_t i = 0; i < n; ++i) x[i] = std::sin(0.1f * i), y[i] = std::cos(0.37f * i);
      std::vector<float> b = y, s = y;
      blend_inplace(b.data(), x.data(), 0.3f, n);
      add_inplace(s.data(), x.data(), n);
      expect_guard_intact(b, n, kSentinel);
      expect_guard_intact(s, n, kSentinel);
      for (int64_t i = 0; i < n; ++i) {
        ASSERT_NEAR(b[i], 0.3 * x[i] + 0.7 * y[i], 3e-7);
        ASSERT_NEAR(s[i], static_cast<double>(x[i]) + y[i], 3e-7);
      }
    }
  }
}

// Sizes below and above the threading threshold (2^15) and odd chunk ends: every float copied, nothing past n.
TEST(Elementwise, CopyFloats) {
  for (int64_t n : {0, 1, 17, 32767, 32768, 100003}) {
    SCOPED_TRACE(testing::Message() << "n=" << n);
    std::vector<float> x(n + kGuard), y(n + kGuard, kSentinel);
    for (int64_t i = 0; i < n + kGuard; ++i) x[i] = float(i) * 0.5f - 3.0f;
    copy_floats(y.data(), x.data(), n);
    expect_guard_intact(y, n, kSentinel);
    for (int64_t i = 0; i < n; ++i) ASSERT_EQ(y[i], x[i]) << i;
  }
}

}  // namespace
}  // namespace egopd
