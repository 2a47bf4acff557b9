// gemm_geglu (a linear layer's GEGLU in one GEMM): against a double-precision reference in float32, and bit for bit
// against the plain GEMM into a [M, 2D] temporary followed by geglu in every precision, on every kernel path: pairs
// of whole panels (D a multiple of the path's NR), the fallback for other D, several K passes, row and thread tails.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernel_reference.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/gemm.h"
#include "core/kernels/gemm_internal.h"
#include "core/threading.h"

namespace egopd {
namespace {

using test::kU;

struct GegluCase {
  int64_t M, D, K;
  DType dt = DType::F16;
  bool bias = true;
  Precision precision = Precision::Fp32;
};

std::string describe(const GegluCase& c) {
  return std::to_string(c.M) + "x(2*" + std::to_string(c.D) + ")x" + std::to_string(c.K) + " " + dtype_name(c.dt) +
         (c.bias ? " bias " : " ") + precision_name(c.precision) + " threads " + std::to_string(num_threads());
}

// Runs one case; returns the number of failures.
int run_case(const GegluCase& c, uint32_t seed) {
  std::mt19937 rng(seed);
  const test::StoredWeight w(size_t(2 * c.D * c.K), c.dt, rng, size_t(c.K));  // W [2D, K]: value rows, gate rows
  Operand wb = w.operand(c.K);
  wb.trans = true;
  const std::vector<float> x = test::random_vec(size_t(c.M * c.K), rng), bias = test::random_vec(size_t(2 * c.D), rng);
  const float* b = c.bias ? bias.data() : nullptr;
  const int64_t ldo = c.D + 3;  // padded rows: the padding must stay untouched
  std::vector<float> out(size_t(c.M * ldo), 7.0f), p(size_t(c.M * 2 * c.D)), want(size_t(c.M * c.D));
  {
    const test::PrecisionGuard precision(c.precision);
    // The scratch only where gemm_geglu_needs_scratch says so: were it wrong, gemm_geglu would throw.
    std::vector<float> scratch(gemm_geglu_needs_scratch(c.D, c.K) ? size_t(c.M * 2 * c.D) : 0);
    gemm_geglu(c.M, c.D, c.K, f32_operand(x.data(), c.K), wb, b, out.data(), ldo,
               scratch.empty() ? nullptr : scratch.data());
    gemm(c.M, 2 * c.D, c.K, f32_operand(x.data(), c.K), wb, p.data(), 2 * c.D, Epilogue{b});
    geglu(p.data(), c.M, c.D, want.data());
  }
  int bad = 0;
  const auto report = [&] { return bad++ < 3; };  // the first three failures are printed, all are counted
  for (int64_t i = 0; i < c.M; ++i) {
    for (int64_t j = 0; j < c.D; ++j) {
      const float got = out[size_t(i * ldo + j)];
      if (got != want[size_t(i * c.D + j)] && report())  // the same arithmetic as the unfused layer, bit for bit
        ADD_FAILURE() << describe(c) << ": (" << i << "," << j << ") " << got << " against unfused "
                      << want[size_t(i * c.D + j)];
      if (c.precision != Precision::Fp32) continue;  // gemm_test checks the reduced-precision products exactly
      double v = c.bias ? bias[size_t(j)] : 0, g = c.bias ? bias[size_t(c.D + j)] : 0;
      double va = std::fabs(v), ga = std::fabs(g);
      for (int64_t k = 0; k < c.K; ++k) {
        const double xv = x[size_t(i * c.K + k)];
        v += xv * w.value[size_t(j * c.K + k)];
        g += xv * w.value[size_t((c.D + j) * c.K + k)];
        va += std::fabs(xv * w.value[size_t(j * c.K + k)]);
        ga += std::fabs(xv * w.value[size_t((c.D + j) * c.K + k)]);
      }
      const double gelu = test::act_ref(Act::GELU, g), ref = v * gelu;
      // Float32 dot products (2 (K + 3) u of their absolute sums), GELU's slope (< 1.2) on the gate's error, and
      // the GEGLU row kernel's own accuracy (elementwise_test: 1e-6 |value gate|).
      const double ev = 2.0 * double(c.K + 3) * kU * va, eg = 2.0 * double(c.K + 3) * kU * ga;
      const double tol = std::fabs(gelu) * ev + (std::fabs(v) + ev) * 1.2 * eg + 1e-6 * std::fabs(v * g) + 1e-30;
      if (!(std::fabs(got - ref) <= tol) && report())
        ADD_FAILURE() << describe(c) << ": (" << i << "," << j << ") " << got << " want " << ref << " tol " << tol;
    }
    for (int64_t j = c.D; j < ldo; ++j)
      if (out[size_t(i * ldo + j)] != 7.0f && report()) ADD_FAILURE() << describe(c) << ": wrote past row " << i;
  }
  return bad;
}

class GemmGegluTest : public test::KernelPathTest {};

TEST_P(GemmGegluTest, PairsOfPanelsMatchTheUnfusedLayer) {
  const int64_t nr = gemm_detail::gemm_path().nr, kc = gemm_detail::gemm_path().kc;
  // D = NR (one pair), 5 NR (pairs split unevenly between two threads), 24 NR (several column blocks per thread
  // on the narrow paths); M over row tails and both ways of splitting the work; K of one and of several passes.
  const GegluCase cases[] = {{1, nr, 7},          {13, nr, 40},      {130, 5 * nr, 64},   {7, 5 * nr, 300},
                             {450, 2 * nr, 33},   {37, 24 * nr, 20}, {29, 3 * nr, 2 * kc + 11}};
  uint32_t seed = 1;
  const int saved = num_threads();
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    for (GegluCase c : cases)
      for (DType dt : {DType::F16, DType::F32, DType::I8})
        for (bool bias : {true, false}) {
          c.dt = dt;
          c.bias = bias;
          EXPECT_EQ(run_case(c, seed++), 0);
        }
  }
  set_num_threads(saved);
}

TEST_P(GemmGegluTest, ScratchIsAskedForWhereTheProjectionIsStored) {
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  EXPECT_FALSE(gemm_geglu_needs_scratch(path.nr, 7));
  EXPECT_TRUE(gemm_geglu_needs_scratch(path.nr + 1, 7));
  EXPECT_TRUE(gemm_geglu_needs_scratch(path.nr, 2 * path.kc + 1));
  std::vector<float> x(6 * 3), w(size_t(2 * (path.nr + 1) * 3)), out(size_t(6 * (path.nr + 1)));
  Operand wb = f32_operand(w.data(), 3, true);
  try {
    gemm_geglu(6, path.nr + 1, 3, f32_operand(x.data(), 3), wb, nullptr, out.data(), path.nr + 1, nullptr);
    ADD_FAILURE() << "no error without the scratch it needs";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("gemm_geglu"), std::string::npos) << e.what();
  }
}

TEST_P(GemmGegluTest, WidthsOutsidePairsFallBack) {
  // D not a multiple of NR: the plain GEMM into the caller's scratch, then geglu (the same contract).
  uint32_t seed = 100;
  for (int64_t D : {1, 5, 17, 50})
    for (int64_t M : {1, 9, 70}) EXPECT_EQ(run_case({M, D, 23}, seed++), 0);
}

TEST_P(GemmGegluTest, ReducedPrecisionsMatchTheUnfusedLayer) {
  const int64_t nr = gemm_detail::gemm_path().nr;
  uint32_t seed = 200;
  for (Precision p : {Precision::Bf16, Precision::Int8})
    for (auto [M, D, K] : {std::tuple<int64_t, int64_t, int64_t>{13, nr, 40}, {130, 5 * nr, 600}, {3, 8 * nr, 1100}})
      for (DType dt : {DType::F16, DType::I8}) EXPECT_EQ(run_case({M, D, K, dt, true, p}, seed++), 0);
}

INSTANTIATE_TEST_SUITE_P(Paths, GemmGegluTest, ::testing::ValuesIn(test::kAllKernelPaths),
                         test::kernel_path_test_name);

}  // namespace
}  // namespace egopd
