// SGEMM against a double-precision triple loop: every transpose, operand dtype, epilogue and awkward shape, on every
// kernel path (portable, AVX2, AVX-512). Tolerance from the float32 dot-product error bound:
//   |err| <= 2 (K + 3) u sum_k |a_ik b_kj| (+ the bias / residual terms) + 8 u |ref|,   u = 2^-24,
// scaled by the activation's Lipschitz constant (<= 1.2 for SiLU, GELU, QuickGELU).
#include <gtest/gtest.h>

#include "core/kernel_reference.h"
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/kernels/gemm.h"
#include "core/kernels/gemm_internal.h"
#include "core/memory.h"
#include "core/threading.h"

namespace egopd {
namespace {

using test::act_ref;
using test::kU;
using test::round_bf16;

// A logical [rows, cols] matrix stored in some dtype, possibly transposed, with a padded leading dimension.
struct StoredMatrix {
  int64_t rows = 0, cols = 0, ld = 0;
  bool trans = false;
  DType dtype = DType::F32;
  std::vector<float> f32;
  std::vector<uint16_t> h16;
  std::vector<int8_t> i8;
  std::vector<float> scale;  // I8: per row (A) or per column (B)
  std::vector<double> value; // exact value of each logical element, row-major [rows, cols]

  // ld_at_least > 0: the leading dimension is the smallest multiple of it >= inner, not inner + 3.
  StoredMatrix(int64_t r, int64_t c, bool tr, DType dt, bool scale_per_row, std::mt19937& rng, int64_t ld_at_least = 0)
      : rows(r), cols(c), trans(tr), dtype(dt) {
    std::uniform_real_distribution<float> u(-1.0f, 1.0f);
    const int64_t outer = tr ? c : r, inner = tr ? r : c;
    ld = ld_at_least > 0 ? (inner + ld_at_least - 1) / ld_at_least * ld_at_least
                         : inner + 3;  // not the dense stride, to catch ld mix-ups
    const size_t n = size_t(outer * ld);
    value.assign(size_t(r * c), 0.0);
    if (dt == DType::I8) {
      const int64_t nscale = scale_per_row ? r : c;
      for (int64_t i = 0; i < nscale; ++i) scale.push_back(0.01f + 0.02f * float(i % 5));
    }
    f32.assign(n, 0.0f);
    h16.assign(n, 0);
    i8.assign(n, 0);
    std::uniform_int_distribution<int> q(-127, 127);
    for (int64_t i = 0; i < r; ++i)
      for (int64_t j = 0; j < c; ++j) {
        const size_t idx = size_t(tr ? j * ld + i : i * ld + j);
        double v;
        switch (dt) {
          case DType::F32: f32[idx] = u(rng); v = f32[idx]; break;
          case DType::F16: h16[idx] = float_to_half(u(rng)); v = half_to_float(h16[idx]); break;
          case DType::BF16: h16[idx] = float_to_bf16(u(rng)); v = bf16_to_float(h16[idx]); break;
          default: i8[idx] = int8_t(q(rng)); v = double(float(i8[idx]) * scale[scale_per_row ? i : j]); break;
        }
        value[size_t(i * c + j)] = v;
      }
  }
  Operand operand() const {
    const void* p = dtype == DType::F32 ? static_cast<const void*>(f32.data())
                    : dtype == DType::I8 ? static_cast<const void*>(i8.data())
                                         : static_cast<const void*>(h16.data());
    return Operand{p, dtype, ld, trans, scale.empty() ? nullptr : scale.data()};
  }
  double at(int64_t i, int64_t j) const { return value[size_t(i * cols + j)]; }
};

struct Case {
  int64_t M, N, K;
  DType adt = DType::F32, bdt = DType::F32;
  bool ta = false, tb = false;
  Act act = Act::None;
  int bias = 0;  // 0 none, 1 per column, 2 per row
  bool accumulate = false;
  bool bf16 = false;  // Precision::Bf16: the reference multiplies the operands rounded to bfloat16
  bool int8 = false;  // Precision::Int8: the reference multiplies the operands quantised per K block (Int8Reference)
  int64_t lda_multiple = 0;  // > 0: A's leading dimension a multiple of this (else its inner size + 3)
};

std::string describe(const Case& c) {
  return std::to_string(c.M) + "x" + std::to_string(c.N) + "x" + std::to_string(c.K) + " A " + dtype_name(c.adt) +
         (c.ta ? "^T" : "") + " B " + dtype_name(c.bdt) + (c.tb ? "^T" : "") + " act " +
         std::to_string(int(c.act)) + " bias " + std::to_string(c.bias) + (c.accumulate ? " acc" : "") +
         (c.bf16 ? " bf16" : "") + (c.int8 ? " int8" : "");
}

// Precision::Int8 as gemm.h defines it, written out plainly: K in balanced blocks of at most kInt8Block; in each,
// every row of A and column of B gets m = max|x|, q = nearbyint(x * (L / m)) clamped to +-L (float32 arithmetic,
// zeros when m <= 1e-30) and the scale m / L, with L = 127 for A and int8_b_levels() for B (63 on the AVX2 path).
// dot() is the exact sum over blocks of (sum of q_a q_b) * s_a * s_b in double, and the sum of the magnitudes of
// its terms.
struct Int8Reference {
  struct Lanes {
    std::vector<int32_t> q;  // q[lane * len + k]
    std::vector<double> scale;
  };
  std::vector<int64_t> starts;  // block b covers K indices [starts[b], starts[b + 1])
  std::vector<Lanes> a, b;      // per block: A's rows, B's columns

  static Lanes quantize(int64_t lanes, int64_t k0, int64_t k1, int levels,
                        const std::function<float(int64_t, int64_t)>& x) {
    Lanes l;
    l.q.resize(size_t(lanes * (k1 - k0)));
    const float L = float(levels);
    for (int64_t i = 0; i < lanes; ++i) {
      float m = 0.0f;
      for (int64_t k = k0; k < k1; ++k) m = std::max(m, std::fabs(x(i, k)));
      const float inv = m > 1e-30f ? L / m : 0.0f;
      l.scale.push_back(m > 1e-30f ? double(m / L) : 0.0);
      for (int64_t k = k0; k < k1; ++k)
        l.q[size_t(i * (k1 - k0) + k - k0)] = int32_t(std::clamp(std::nearbyint(x(i, k) * inv), -L, L));
    }
    return l;
  }
  Int8Reference(const StoredMatrix& A, const StoredMatrix& B, int64_t M, int64_t N, int64_t K) {
    const int64_t blocks = std::max<int64_t>(1, (K + kInt8Block - 1) / kInt8Block), len = (K + blocks - 1) / blocks;
    for (int64_t k0 = 0; k0 < K || k0 == 0; k0 += len) {
      const int64_t k1 = std::min(K, k0 + len);
      starts.push_back(k0);
      a.push_back(quantize(M, k0, k1, 127, [&](int64_t i, int64_t k) { return float(A.at(i, k)); }));
      b.push_back(quantize(N, k0, k1, int8_b_levels(), [&](int64_t j, int64_t k) { return float(B.at(k, j)); }));
      if (k1 >= K) break;
    }
    starts.push_back(K);
  }
  void dot(int64_t i, int64_t j, double* sum, double* magnitude) const {
    *sum = *magnitude = 0;
    for (size_t blk = 0; blk < a.size(); ++blk) {
      const int64_t len = starts[blk + 1] - starts[blk];
      int64_t s = 0;
      for (int64_t k = 0; k < len; ++k) s += int64_t(a[blk].q[size_t(i * len + k)]) * b[blk].q[size_t(j * len + k)];
      const double term = double(s) * a[blk].scale[size_t(i)] * b[blk].scale[size_t(j)];
      *sum += term;
      *magnitude += std::fabs(term);
    }
  }
};

// Runs gemm on one case and checks every element against the bound; returns the number of failures.
int run_case(const Case& c, uint32_t seed) {
  std::mt19937 rng(seed);
  StoredMatrix A(c.M, c.K, c.ta, c.adt, true, rng, c.lda_multiple), B(c.K, c.N, c.tb, c.bdt, false, rng);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  std::vector<float> bias(size_t(c.bias == 2 ? c.M : c.N));
  for (auto& v : bias) v = u(rng);
  const int64_t ldc = c.N + 5;
  std::vector<float> C(size_t(c.M * ldc));
  for (auto& v : C) v = u(rng);
  const std::vector<float> C0 = C;
  Epilogue ep;
  ep.bias = c.bias ? bias.data() : nullptr;
  ep.bias_per_row = c.bias == 2;
  ep.act = c.act;
  ep.accumulate = c.accumulate;
  {
    const test::PrecisionGuard precision(test::precision_of(c.bf16, c.int8));
    gemm(c.M, c.N, c.K, A.operand(), B.operand(), C.data(), ldc, ep);
  }
  std::optional<Int8Reference> q8;
  if (c.int8) q8.emplace(A, B, c.M, c.N, c.K);
  int bad = 0;
  for (int64_t i = 0; i < c.M; ++i)
    for (int64_t j = 0; j < c.N; ++j) {
      double s = 0, sa = 0;
      // Int8: each block's term is rounded twice (the scale product, the scaled sum) and added to C in float32:
      // the float32 bound below with one "product" per block.
      if (q8) q8->dot(i, j, &s, &sa);
      for (int64_t k = 0; k < (q8 ? 0 : c.K); ++k) {
        const double a = c.bf16 ? round_bf16(A.at(i, k)) : A.at(i, k), b = c.bf16 ? round_bf16(B.at(k, j)) : B.at(k, j);
        s += a * b;
        sa += std::fabs(a * b);
      }
      if (c.bias) {
        const double b = bias[size_t(c.bias == 2 ? i : j)];
        s += b;
        sa += std::fabs(b);
      }
      double ref = act_ref(c.act, s);
      const double lip = c.act == Act::None ? 1.0 : 1.2;
      const double terms = q8 ? double(q8->a.size()) : double(c.K);
      double tol = lip * 2.0 * (terms + 3) * kU * sa + 8 * kU * std::fabs(ref) + 1e-30;
      if (c.accumulate) {
        ref += C0[size_t(i * ldc + j)];
        tol += 4 * kU * (std::fabs(C0[size_t(i * ldc + j)]) + std::fabs(ref));
      }
      const double got = C[size_t(i * ldc + j)];
      if (!(std::fabs(got - ref) <= tol)) {
        if (bad < 3)
          ADD_FAILURE() << describe(c) << " at (" << i << "," << j << "): got " << got << " want " << ref
                        << " tol " << tol;
        ++bad;
      }
    }
  // The padding between rows of C is untouched.
  for (int64_t i = 0; i < c.M; ++i)
    for (int64_t j = c.N; j < ldc; ++j)
      if (C[size_t(i * ldc + j)] != C0[size_t(i * ldc + j)]) {
        if (bad < 3) ADD_FAILURE() << describe(c) << ": wrote outside C at (" << i << "," << j << ")";
        ++bad;
      }
  return bad;
}

class GemmTest : public test::KernelPathTest {};

TEST_P(GemmTest, AwkwardShapesAllTransposes) {
  uint32_t seed = 1;
  // Tiles: 6 x 16 (portable, avx2), 12 x 32 (avx512), 8 x 12 (neon: N = 12, 24 full; 16, 20, 28 tails of 4, 8, 4).
  for (int64_t M : {1, 5, 6, 7, 8, 17, 33, 127})
    for (int64_t N : {1, 7, 12, 15, 16, 17, 20, 24, 28, 31, 65})
      for (int64_t K : {1, 7, 17, 31})
        for (int t = 0; t < 4; ++t) {
          Case c{M, N, K};
          c.ta = t & 1;
          c.tb = t & 2;
          ASSERT_EQ(run_case(c, seed++), 0);
        }
}

TEST_P(GemmTest, LargeAndMultiBlockShapes) {
  // 300x257x129: tails everywhere; K = 800, 1000 and 2 KC + 37: several K passes (the last on every path's KC);
  // M = 450: several M blocks per thread; N = 2100: several column blocks; M < N: the threads split N instead of
  // M, unsynchronised, through K blocks of unequal depth and column blocks of unequal width (10 x 2060 x 800).
  const int64_t kc = gemm_detail::gemm_path().kc;
  const Case cases[] = {{300, 257, 129}, {97, 45, 800}, {450, 33, 70}, {13, 2100, 9}, {3, 1000, 40},
                        {64, 320, 1000}, {10, 2060, 800}, {40, 70, 2 * kc + 37}};
  uint32_t seed = 100;
  for (Case c : cases)
    for (int t = 0; t < 4; ++t) {
      c.ta = t & 1;
      c.tb = t & 2;
      ASSERT_EQ(run_case(c, seed++), 0);
    }
}

TEST_P(GemmTest, RowsFourKiBApart) {
  // Float32 A whose rows are a multiple of 4 KiB apart is packed instead of read in place (its rows would share
  // one L1 set): the same results, with tails in every direction.
  uint32_t seed = 150;
  for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{37, 50, 1024}, {13, 33, 700}, {30, 17, 2100}})
    for (int t = 0; t < 4; ++t) {
      Case c{M, N, K};
      c.ta = t & 1;
      c.tb = t & 2;
      c.lda_multiple = 1024;
      c.bias = 1 + t % 2;
      ASSERT_EQ(run_case(c, seed++), 0);
    }
}

TEST_P(GemmTest, OperandDtypes) {
  uint32_t seed = 200;
  for (DType dt : {DType::F16, DType::BF16, DType::I8})
    for (int t = 0; t < 4; ++t)
      for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{37, 50, 45}, {12, 32, 16}, {130, 70, 400}}) {
        Case b{M, N, K, DType::F32, dt, false, bool(t & 1)};  // weights as B (linear layers)
        Case a{M, N, K, dt, DType::F32, bool(t & 2), false};  // weights as A (convolutions)
        ASSERT_EQ(run_case(b, seed++), 0);
        ASSERT_EQ(run_case(a, seed++), 0);
      }
}

TEST_P(GemmTest, Epilogues) {
  uint32_t seed = 300;
  const int64_t two_passes = gemm_detail::gemm_path().kc + 5;  // a K of two passes (19: one)
  for (Act act : {Act::None, Act::SiLU, Act::GELU, Act::QuickGELU})
    for (int bias : {0, 1, 2})
      for (bool acc : {false, true})
        for (int64_t K : {int64_t(19), two_passes}) {  // accumulate + act over two passes goes through a temporary
          Case c{29, 37, K};
          c.tb = true;
          c.act = act;
          c.bias = bias;
          c.accumulate = acc;
          ASSERT_EQ(run_case(c, seed++), 0);
          for (auto [M, N] : {std::pair<int64_t, int64_t>{12, 32}, {24, 48}}) {  // full tiles of every path only:
            Case full{M, N, K};                                                   // the fused vector epilogue
            full.act = act;
            full.bias = bias;
            full.accumulate = acc;
            ASSERT_EQ(run_case(full, seed++), 0);
          }
        }
}

TEST_P(GemmTest, ZeroDepthGivesBiasAndActivation) {
  Case c{5, 9, 0};
  c.bias = 1;
  c.act = Act::SiLU;
  EXPECT_EQ(run_case(c, 400), 0);
  c.accumulate = true;
  EXPECT_EQ(run_case(c, 401), 0);
}

TEST_P(GemmTest, SerialInsideParallelRegion) {
  int bad = 0;
#pragma omp parallel num_threads(2) reduction(+ : bad)
  {
    Case c{70, 90, 500};
    c.tb = true;
    c.bias = 1;
    bad += run_case(c, 500 + uint32_t(omp_get_thread_num()));
  }
  EXPECT_EQ(bad, 0);
}

TEST_P(GemmTest, OneThreadAndTwoThreadsAgree) {
  // Thread count changes only the partition of the work, never the summation order of an element. N = 150:
  // the threads split columns; N = 40: they split rows (shared B blocks over two K blocks). In bf16 and int8 the
  // threads split rows up to N = 320 (A is rounded or quantised once) and columns at N = 700 (each thread
  // rounds or quantises all of A for its own columns).
  const int saved = num_threads();
  const Precision saved_precision = precision();
  for (Precision p : {Precision::Fp32, Precision::Bf16, Precision::Int8})
    for (int64_t N : {150, 40, 700}) {
      set_precision(p);
      std::mt19937 rng(7);
      StoredMatrix A(200, 700, false, DType::F32, true, rng), B(700, N, true, DType::F16, false, rng);
      std::vector<float> c1(size_t(200 * N)), c2(size_t(200 * N));
      set_num_threads(1);
      gemm(200, N, 700, A.operand(), B.operand(), c1.data(), N);
      set_num_threads(2);
      gemm(200, N, 700, A.operand(), B.operand(), c2.data(), N);
      EXPECT_EQ(c1, c2) << precision_name(p) << ", N = " << N;
    }
  set_precision(saved_precision);
  set_num_threads(saved);
}

// Precision::Bf16 (native vdpbf16ps where the path has it, else emulated): the products of the bfloat16-rounded
// operands, summed in float32, so the float32 bound above applies against a reference that rounds its operands
// alike. Odd K (the last bfloat16 pair half empty), every operand dtype, transposes, tails, several K passes.
TEST_P(GemmTest, Bf16ComputeMultipliesRoundedOperands) {
  uint32_t seed = 600;
  for (int64_t M : {1, 7, 9, 12, 13, 50})
    for (int64_t N : {1, 15, 32, 33, 70})
      for (int64_t K : {1, 2, 7, 16, 17, 31, 700})
        for (int t = 0; t < 4; ++t) {
          Case c{M, N, K};
          c.ta = t & 1;
          c.tb = t & 2;
          c.bf16 = true;
          ASSERT_EQ(run_case(c, seed++), 0);
        }
  // Float32 A: K tails of 16, two K passes, several row blocks; 20 x 700: the threads split N, each rounding all
  // of A for its columns.
  for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{5, 40, 2900}, {300, 64, 47}, {25, 33, 1345},
                         {20, 700, 1500}}) {
    Case c{M, N, K};
    c.bf16 = true;
    c.bias = 1;
    ASSERT_EQ(run_case(c, seed++), 0);
  }
  for (DType dt : {DType::F16, DType::BF16, DType::I8})
    for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{37, 50, 45}, {130, 70, 1001}}) {
      Case b{M, N, K, DType::F32, dt, false, true};
      Case a{M, N, K, dt, DType::F32, false, false};
      b.bf16 = a.bf16 = true;
      b.bias = 1, a.bias = 2;
      b.act = Act::GELU, a.accumulate = true;
      ASSERT_EQ(run_case(b, seed++), 0);
      ASSERT_EQ(run_case(a, seed++), 0);
      // The other layout of each: lanes consecutive in memory (B as [K, N], A as [K, M]).
      Case bc{M, N, K, DType::F32, dt, false, false}, ac{M, N, K, dt, DType::F32, true, false};
      bc.bf16 = ac.bf16 = true;
      ASSERT_EQ(run_case(bc, seed++), 0);
      ASSERT_EQ(run_case(ac, seed++), 0);
    }
}

// Precision::Int8 (vpdpbusd, vpmaddubsw or the scalar emulation, whichever the path has): exactly the products of
// the operands quantised as gemm.h defines, against the reference above, so a wrong scale, rounding, block split,
// sign offset, level count or lost K tail fails by whole quantisation steps. Odd K (quad tails), one and several K
// blocks, every operand dtype, transposes, tails and epilogues.
TEST_P(GemmTest, Int8ComputeMultipliesQuantisedOperands) {
  uint32_t seed = 900;
  for (int64_t M : {1, 7, 12, 13, 50})
    for (int64_t N : {1, 15, 32, 33, 70})
      for (int64_t K : {1, 2, 3, 5, 31, 700})
        for (int t = 0; t < 4; ++t) {
          Case c{M, N, K};
          c.ta = t & 1;
          c.tb = t & 2;
          c.int8 = true;
          ASSERT_EQ(run_case(c, seed++), 0);
        }
  // 20 x 700, 9 x 900, 13 x 650: the threads split N, each quantising all of A for its columns (1537: three
  // groups in one pass; 1100: two passes).
  for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{20, 700, 1537}, {9, 900, 1100}, {13, 650, 30}})
    for (int t = 0; t < 2; ++t) {
      Case c{M, N, K};
      c.ta = t & 1;
      c.int8 = true;
      c.bias = 1;
      ASSERT_EQ(run_case(c, seed++), 0);
    }
  for (DType dt : {DType::F16, DType::BF16, DType::I8})
    for (auto [M, N, K] : {std::tuple<int64_t, int64_t, int64_t>{37, 50, 45}, {130, 70, 1537}}) {
      Case b{M, N, K, DType::F32, dt, false, true};
      Case a{M, N, K, dt, DType::F32, false, false};
      b.int8 = a.int8 = true;
      b.bias = 1, a.bias = 2;
      b.act = Act::GELU, a.accumulate = true;
      ASSERT_EQ(run_case(b, seed++), 0);
      ASSERT_EQ(run_case(a, seed++), 0);
    }
}

// Int8 with non-finite operands, as float32 would: a NaN anywhere in a row of A or column of B (here before finite
// values, in the first of two groups, and in the second) makes that row's or column's outputs NaN, an inf makes them
// non-finite; every other output is bit for bit what it is without them (the scales are per row and column). Row A
// read in place (fused quantiser) and packed (transposed), B in both layouts.
TEST_P(GemmTest, Int8NonFiniteOperandsGiveNonFiniteOutputs) {
  const int64_t M = 13, N = 37, K = 700;
  std::mt19937 rng(77);
  for (int t = 0; t < 4; ++t) {
    const bool ta = t & 1, tb = t & 2;
    const std::vector<float> a0 = test::random_vec(size_t(M * K), rng), b0 = test::random_vec(size_t(K * N), rng);
    const auto a_at = [&](int64_t i, int64_t k) { return size_t(ta ? k * M + i : i * K + k); };
    const auto b_at = [&](int64_t k, int64_t j) { return size_t(tb ? j * K + k : k * N + j); };
    std::vector<float> a = a0, b = b0;
    a[a_at(1, 3)] = NAN;                        // row 1: first group, finite values after it
    a[a_at(7, 650)] = NAN;                      // row 7: second group
    a[a_at(9, 100)] = INFINITY;                 // row 9
    b[b_at(5, 2)] = NAN;                        // column 2
    b[b_at(690, 31)] = -INFINITY;               // column 31
    const test::PrecisionGuard int8(Precision::Int8);
    std::vector<float> c(size_t(M * N)), c0(c.size());
    gemm(M, N, K, {a.data(), DType::F32, ta ? M : K, ta}, {b.data(), DType::F32, tb ? K : N, tb}, c.data(), N);
    gemm(M, N, K, {a0.data(), DType::F32, ta ? M : K, ta}, {b0.data(), DType::F32, tb ? K : N, tb}, c0.data(), N);
    for (int64_t i = 0; i < M; ++i)
      for (int64_t j = 0; j < N; ++j) {
        const float v = c[size_t(i * N + j)];
        if (i == 1 || i == 7 || j == 2)
          EXPECT_TRUE(std::isnan(v)) << "ta " << ta << " tb " << tb << " (" << i << ", " << j << "): " << v;
        else if (i == 9 || j == 31)
          EXPECT_FALSE(std::isfinite(v)) << "ta " << ta << " tb " << tb << " (" << i << ", " << j << "): " << v;
        else
          EXPECT_EQ(v, c0[size_t(i * N + j)]) << "ta " << ta << " tb " << tb << " (" << i << ", " << j << ")";
      }
  }
}

// The same int8 result on 1 and 2 threads (splitting M and N) and on every path that quantises B alike (bit for
// bit: the int32 sums are exact and each path scales them with the same float32 operations; no activation, whose
// SIMD polynomials differ). The AVX2 path's 63 levels of B give other numbers (the check above).
TEST(GemmInt8Test, ThreadsAndPathsAgreeBitForBit) {
  const int saved = num_threads();
  std::mt19937 rng(77);
  for (int64_t N : {40, 300, 1000}) {  // 40, 300: the threads split M; 1000: they split N
    StoredMatrix A(200, 700, false, DType::F32, true, rng), B(700, N, true, DType::F16, false, rng);
    std::map<int, std::vector<float>> first;  // by int8_b_levels()
    for (KernelPath p : supported_kernel_paths())
      for (int threads : {1, 2}) {
        test::KernelPathGuard guard(p);
        set_num_threads(threads);
        const test::PrecisionGuard int8(Precision::Int8);
        std::vector<float> c(size_t(200 * N));
        gemm(200, N, 700, A.operand(), B.operand(), c.data(), N);
        std::vector<float>& want = first[int8_b_levels()];
        if (want.empty()) want = c;
        EXPECT_EQ(c, want) << kernel_path_name(p) << ", " << threads << " threads, N = " << N;
      }
  }
  set_num_threads(saved);
}

// Each path multiplies int8 with the instruction the CPU has: the checks above then test that kernel (under
// qemu-aarch64, whose CPU has the dot product, the sdot one).
TEST(GemmInt8Test, KernelFollowsTheCpu) {
  const CpuInfo& ci = cpu_info();
  for (KernelPath p : supported_kernel_paths()) {
    test::KernelPathGuard guard(p);
    std::string want = "emulated";
    if (p == KernelPath::Avx512 && ci.avx512_vnni) want = "vpdpbusd (AVX512-VNNI)";
    if (p == KernelPath::Avx2) want = "vpmaddubsw (AVX2, B in 63 levels)";
    if (p == KernelPath::Neon && ci.neon_dotprod) want = "sdot (ARMv8.2 dot product)";
    EXPECT_EQ(std::string(int8_kernel()), want) << kernel_path_name(p);
    EXPECT_EQ(int8_b_levels(), p == KernelPath::Avx2 ? 63 : 127) << kernel_path_name(p);
  }
}

#if defined(__x86_64__)
// The AVX2 int8 A packer (the avx2 path's with 6 rows, the avx512 VNNI path's with 12) writes what the scalar
// quantiser writes for the same rows packed as a float panel: the same quads, scales and sums, byte for byte (finite
// values; a NaN row's bytes differ and are never read: its scale is NaN). Run wherever AVX2 is, so that the 12-row
// packer is checked on CPUs without AVX-512 too. Short rows (mr < MR), K tails of 1-7, several and uneven groups.
template <int MR>
void expect_row_packer_matches_quantiser() {
  std::mt19937 rng(31);
  const int64_t lda = 703;
  for (int mr : {1, 2, 3, 4, 5, MR - 1, MR})
    for (auto [kc, group] : {std::pair<int64_t, int64_t>{1, 1}, {3, 3}, {4, 4}, {5, 5}, {12, 12}, {13, 13}, {31, 16},
                             {700, 350}, {701, 351}})
      for (float magnitude : {1.0f, 3e-3f, 250.0f}) {
        std::vector<float> a = test::random_vec(size_t(MR * lda), rng);
        for (float& v : a) v *= magnitude;
        std::vector<float> panel(size_t(kc * MR), 0.0f);  // [k][row], rows past mr zero
        for (int64_t k = 0; k < kc; ++k)
          for (int i = 0; i < mr; ++i) panel[size_t(k * MR + i)] = a[size_t(i * lda + k)];
        const size_t floats = size_t((kc + group - 1) / group * gemm_detail::i8_region(MR, group));
        std::vector<float> got(floats, -1.0f), want(floats, -1.0f);
        gemm_detail::pack_a_i8_rows_avx2<MR>(a.data(), lda, mr, kc, group, got.data());
        gemm_detail::quantize_i8_quads(panel.data(), want.data(), MR, kc, group, /*unsigned_bytes=*/true);
        ASSERT_EQ(std::memcmp(got.data(), want.data(), floats * sizeof(float)), 0)
            << "MR " << MR << " mr " << mr << " kc " << kc << " group " << group << " magnitude " << magnitude;
      }
}

// The AVX2 int8 B packer, reading the rows of a transposed F32 or F16 B in place, writes what the avx2 path's packer
// and quantiser write through a float panel (pack_b_avx2, then quantize_i8_b_avx2: 16 lanes of 63 levels), byte for
// byte. Short panels (nr < NR), K tails of 1-7, several and uneven groups, three magnitudes.
void expect_b_row_packer_matches_quantiser(DType dt) {
  constexpr int NR = gemm_detail::kNrAvx2;
  std::mt19937 rng(37);
  const int64_t ldb = 705;
  for (int nr : {1, 3, 4, 6, NR - 1, NR})
    for (auto [kc, group] : {std::pair<int64_t, int64_t>{1, 1}, {3, 3}, {5, 5}, {12, 12}, {13, 13}, {31, 16},
                             {700, 350}, {701, 351}})
      for (float magnitude : {1.0f, 3e-3f, 250.0f}) {
        std::vector<float> b = test::random_vec(size_t(NR * ldb), rng);
        std::vector<uint16_t> half(b.size());
        for (size_t i = 0; i < b.size(); ++i) {
          half[i] = float_to_half(b[i] * magnitude);
          b[i] = dt == DType::F16 ? half_to_float(half[i]) : b[i] * magnitude;
        }
        const void* src = dt == DType::F16 ? static_cast<const void*>(half.data()) : b.data();
        std::vector<float> panel(size_t(kc * NR), 0.0f);  // [k][lane], lanes past nr zero
        for (int64_t k = 0; k < kc; ++k)
          for (int j = 0; j < nr; ++j) panel[size_t(k * NR + j)] = b[size_t(j * ldb + k)];
        const size_t floats = size_t((kc + group - 1) / group * gemm_detail::i8_region(NR, group));
        std::vector<float> got(floats, -1.0f), want(floats, -1.0f);
        gemm_detail::pack_b_i8_rows_avx2(src, dt, ldb, nr, kc, group, got.data());
        AlignedScratch packed_buf;  // the packer stores whole aligned vectors
        float* const packed = packed_buf.get(size_t(kc * NR));
        gemm_detail::pack_b_avx2(src, dt, ldb, /*trans=*/true, nullptr, kc, nr, packed);
        ASSERT_TRUE(std::equal(panel.begin(), panel.end(), packed)) << "nr " << nr << " kc " << kc;
        gemm_detail::quantize_i8_b_avx2(panel.data(), want.data(), NR, kc, group);
        ASSERT_EQ(std::memcmp(got.data(), want.data(), floats * sizeof(float)), 0)
            << dtype_name(dt) << " NR " << NR << " nr " << nr << " kc " << kc << " group " << group
            << " magnitude " << magnitude;
      }
}

TEST(GemmInt8Test, AvxBRowPackerMatchesQuantiser) {
  if (!cpu_info().avx2_fma_f16c) GTEST_SKIP() << "needs AVX2";
  for (DType dt : {DType::F32, DType::F16}) expect_b_row_packer_matches_quantiser(dt);
}

TEST(GemmInt8Test, AvxRowPackerMatchesScalarQuantiser) {
  if (!cpu_info().avx2_fma_f16c) GTEST_SKIP() << "needs AVX2";
  expect_row_packer_matches_quantiser<gemm_detail::kMrAvx2>();
  expect_row_packer_matches_quantiser<gemm_detail::kMrAvx512>();
}
#endif

TEST(PrecisionTest, NamesParseBack) {
  for (Precision p : {Precision::Fp32, Precision::Bf16, Precision::Int8}) {
    Precision q = p == Precision::Fp32 ? Precision::Bf16 : Precision::Fp32;
    EXPECT_TRUE(parse_precision(precision_name(p), &q));
    EXPECT_EQ(q, p);
  }
  Precision q;
  EXPECT_FALSE(parse_precision("fp16", &q));
  EXPECT_FALSE(parse_precision("", &q));
  EXPECT_EQ(precision(), Precision::Fp32);  // the default
}

TEST(GemmActTest, ApplyActMatchesDoubleReference) {
  for (Act act : {Act::None, Act::SiLU, Act::GELU, Act::QuickGELU})
    for (float x = -12.0f; x <= 12.0f; x += 0.37f) {
      const double ref = act_ref(act, x);
      EXPECT_NEAR(apply_act(act, x), ref, 4 * kU * (std::fabs(ref) + std::fabs(x)) + 1e-30) << int(act) << " " << x;
    }
}

INSTANTIATE_TEST_SUITE_P(Paths, GemmTest, ::testing::ValuesIn(test::kAllKernelPaths),
                         test::kernel_path_test_name);

}  // namespace
}  // namespace egopd
