// GroupNorm, LayerNorm and softmax against double-precision references, on every kernel path.
#include "core/kernels/norm.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/cpu.h"
#include "core/kernel_reference.h"

namespace egopd {
namespace {


std::vector<float> normal_values(size_t n, float mean, float stddev, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> nd(mean, stddev);
  std::vector<float> v(n);
  for (float& x : v) x = nd(rng);
  return v;
}

// Floats after the output a kernel must not write (one vector of the widest path and more).
constexpr int64_t kGuard = 20;
constexpr float kSentinel = -99.0f;

void expect_guard_intact(const std::vector<float>& v, int64_t n) {
  for (size_t i = n; i < v.size(); ++i) ASSERT_EQ(v[i], kSentinel) << "written past the output at " << i;
}

struct GnCase {
  int64_t batch, frames, c, s, groups;
  float mean = 0.0f, stddev = 1.0f;  // input distribution (an offset mean tests the variance's cancellation)
};

void check_group_norm(const GnCase& g, bool silu, bool affine, bool in_place) {
  const int64_t n = g.batch * g.frames * g.c * g.s;
  const std::vector<float> x = normal_values(n, g.mean, g.stddev, 11 + static_cast<uint32_t>(n));
  const std::vector<float> gamma = normal_values(g.c, 1.0f, 0.5f, 3), beta = normal_values(g.c, 0.0f, 0.5f, 4);
  std::vector<float> y(n + kGuard, kSentinel), buf = x;
  buf.resize(n + kGuard, kSentinel);
  const float eps = 1e-5f;
  const float* gp = affine ? gamma.data() : nullptr;
  const float* bp = affine ? beta.data() : nullptr;
  if (in_place) {
    group_norm(buf.data(), buf.data(), g.batch, g.frames, g.c, g.s, g.groups, gp, bp, eps, silu);
    y = buf;
  } else {
    group_norm(x.data(), y.data(), g.batch, g.frames, g.c, g.s, g.groups, gp, bp, eps, silu);
  }
  expect_guard_intact(y, n);
  const int64_t cg = g.c / g.groups;
  // x[b, f, ch, i] at ((b*frames + f)*c + ch)*s + i
  auto at = [&](int64_t b, int64_t f, int64_t ch, int64_t i) { return ((b * g.frames + f) * g.c + ch) * g.s + i; };
  const double tol = 3e-6 + 3e-7 * std::fabs(g.mean) / g.stddev;  // float inputs near a large mean lose ~ulp(mean)
  for (int64_t b = 0; b < g.batch; ++b)
    for (int64_t grp = 0; grp < g.groups; ++grp) {
      double sum = 0.0, cnt = 0.0;
      for (int64_t f = 0; f < g.frames; ++f)
        for (int64_t ch = grp * cg; ch < (grp + 1) * cg; ++ch)
          for (int64_t i = 0; i < g.s; ++i) sum += x[at(b, f, ch, i)], cnt += 1.0;
      const double mean = sum / cnt;
      double sq = 0.0;
      for (int64_t f = 0; f < g.frames; ++f)
        for (int64_t ch = grp * cg; ch < (grp + 1) * cg; ++ch)
          for (int64_t i = 0; i < g.s; ++i) sq += (x[at(b, f, ch, i)] - mean) * (x[at(b, f, ch, i)] - mean);
      const double rstd = 1.0 / std::sqrt(sq / cnt + eps);
      for (int64_t f = 0; f < g.frames; ++f)
        for (int64_t ch = grp * cg; ch < (grp + 1) * cg; ++ch)
          for (int64_t i = 0; i < g.s; ++i) {
            double ref = (x[at(b, f, ch, i)] - mean) * rstd;
            if (affine) ref = ref * gamma[ch] + beta[ch];
            if (silu) ref = ref / (1.0 + std::exp(-ref));
            ASSERT_NEAR(y[at(b, f, ch, i)], ref, tol * std::max(1.0, std::fabs(ref)))
                << "b=" << b << " f=" << f << " ch=" << ch << " i=" << i;
          }
    }
}

TEST(GroupNorm, AwkwardShapesBothPaths) {
  const GnCase cases[] = {
      {1, 1, 4, 1, 4},         // one value per group: variance 0
      {2, 1, 6, 5, 2},         // c/groups = 3, batch 2
      {1, 1, 9, 13, 9},        // c/groups = 1
      {2, 3, 10, 7, 5},        // 3 frames
      {1, 16, 20, 33, 4},      // video layout, odd c/groups
      {1, 1, 7, 1, 7},         // s = 1
      {2, 1, 64, 37, 32},      // per-frame 4-D, odd s (tails of 8)
      {1, 2, 32, 17, 8},       // s = 17, 68 values a frame and group (tails of 16)
      {2, 1, 30, 15, 3},       // s = 15, 150 values a group
      {1, 3, 12, 31, 4},       // s = 31
      {1, 4, 16, 64, 2, 100.0f, 1.0f},  // large mean relative to the spread
  };
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (const GnCase& g : cases)
      for (int variant = 0; variant < 4; ++variant) {
        const bool silu = variant & 1, affine = variant & 2;
        SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " batch=" << g.batch << " frames="
                                        << g.frames << " c=" << g.c << " s=" << g.s << " groups=" << g.groups
                                        << " silu=" << silu << " affine=" << affine);
        check_group_norm(g, silu, affine, false);
      }
  }
}

TEST(GroupNorm, InPlaceAndLargeVideo) {
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    SCOPED_TRACE(kernel_path_name(path));
    check_group_norm({2, 3, 10, 7, 5}, true, true, true);
    check_group_norm({1, 16, 32, 256, 8}, true, true, false);  // big enough to run in parallel
  }
}

TEST(GroupNorm, RejectsChannelsNotDivisibleByGroups) {
  std::vector<float> x(10, 1.0f);
  EXPECT_THROW(group_norm(x.data(), x.data(), 1, 1, 10, 1, 4, nullptr, nullptr, 1e-5f, false), std::exception);
}

void check_layer_norm(int64_t rows, int64_t c, bool affine, bool in_place, float mean) {
  const std::vector<float> x = normal_values(rows * c, mean, 1.5f, 21 + static_cast<uint32_t>(c));
  const std::vector<float> gamma = normal_values(c, 1.0f, 0.5f, 5), beta = normal_values(c, 0.0f, 0.5f, 6);
  std::vector<float> y(rows * c + kGuard, kSentinel);
  if (in_place) {
    std::copy(x.begin(), x.end(), y.begin());
    layer_norm(y.data(), y.data(), rows, c, affine ? gamma.data() : nullptr, affine ? beta.data() : nullptr, 1e-5f);
  } else {
    layer_norm(x.data(), y.data(), rows, c, affine ? gamma.data() : nullptr, affine ? beta.data() : nullptr, 1e-5f);
  }
  expect_guard_intact(y, rows * c);
  const double tol = 3e-6 + 1e-7 * std::fabs(mean) / 1.5;  // ~ulp(mean) from rounding the mean to float
  for (int64_t r = 0; r < rows; ++r) {
    double sum = 0.0;
    for (int64_t i = 0; i < c; ++i) sum += x[r * c + i];
    const double m = sum / c;
    double sq = 0.0;
    for (int64_t i = 0; i < c; ++i) sq += (x[r * c + i] - m) * (x[r * c + i] - m);
    const double rstd = 1.0 / std::sqrt(sq / c + 1e-5);
    for (int64_t i = 0; i < c; ++i) {
      double ref = (x[r * c + i] - m) * rstd;
      if (affine) ref = ref * gamma[i] + beta[i];
      ASSERT_NEAR(y[r * c + i], ref, tol * std::max(1.0, std::fabs(ref))) << "r=" << r << " i=" << i;
    }
  }
}

TEST(LayerNorm, AwkwardWidthsBothPaths) {
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (int64_t c : {1, 3, 7, 8, 13, 15, 16, 17, 31, 33, 63, 65, 100, 320, 1024, 1281, 1283})
      for (int variant = 0; variant < 4; ++variant) {
        const bool affine = variant & 1, in_place = variant & 2;
        SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " c=" << c << " affine=" << affine
                                        << " in_place=" << in_place);
        check_layer_norm(3, c, affine, in_place, 0.0f);
      }
    SCOPED_TRACE(kernel_path_name(path));
    check_layer_norm(5, 77, true, false, 50.0f);     // offset mean
    check_layer_norm(5, 1281, true, false, 50.0f);   // offset mean over a wide row
    check_layer_norm(3, 1281, false, false, 1000.0f);
    check_layer_norm(200, 320, true, false, 0.0f);   // parallel
  }
}

TEST(Softmax, RowsWithMasksAndLargeValues) {
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    for (int64_t cols : {1, 5, 8, 15, 16, 17, 31, 33, 77, 100, 1030}) {
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " cols=" << cols);
      const int64_t rows = cols > 100 ? 40 : 4;
      std::vector<float> x = normal_values(rows * cols, 0.0f, 3.0f, 31 + static_cast<uint32_t>(cols));
      for (int64_t j = 0; j < cols; ++j) x[cols + j] += 1000.0f;                   // row 1: exp would overflow
      for (int64_t j = 1; j < cols; j += 2) x[2 * cols + j] = -INFINITY;            // row 2: masked entries
      x.resize(rows * cols + kGuard, kSentinel);
      const std::vector<float> in = x;
      softmax_rows(x.data(), rows, cols);
      expect_guard_intact(x, rows * cols);
      for (int64_t r = 0; r < rows; ++r) {
        double mx = -INFINITY, sum = 0.0;
        for (int64_t j = 0; j < cols; ++j) mx = std::max(mx, static_cast<double>(in[r * cols + j]));
        for (int64_t j = 0; j < cols; ++j) sum += std::exp(in[r * cols + j] - mx);
        for (int64_t j = 0; j < cols; ++j) {
          const double ref = std::exp(in[r * cols + j] - mx) / sum;
          ASSERT_NEAR(x[r * cols + j], ref, 2e-6 * ref + 1e-12) << "r=" << r << " j=" << j;
        }
      }
    }
  }
}

}  // namespace
}  // namespace egopd
