// Attention against a double-precision naive softmax(QK^T scale)V, on every kernel path.
#include "core/kernels/attention.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/cpu.h"
#include "core/kernel_reference.h"

namespace egopd {
namespace {


struct Case {
  int64_t batch, heads, lq, lk, dh;
  bool causal = false;
  bool fused = false;   // q, k, v as column slices of one [rows, 3*C] buffer (self-attention only)
  float amplitude = 1;  // q and k range (v is in [-1, 1]); large values test the max subtraction
};

// Runs one case on the current path and checks every output against the double reference.
void check_case(const Case& c, uint32_t seed) {
  const int64_t C = c.heads * c.dh;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ud(-c.amplitude, c.amplitude), vd(-1.0f, 1.0f);
  std::vector<float> qb, kb, vb;
  AttentionArgs a;
  a.batch = c.batch, a.heads = c.heads, a.lq = c.lq, a.lk = c.lk, a.dh = c.dh;
  a.scale = 1.0f / std::sqrt(static_cast<float>(c.dh));
  a.causal = c.causal;
  if (c.fused) {  // [batch, rows, 3C]: q | k | v
    qb.resize(c.batch * c.lq * 3 * C);
    for (int64_t i = 0; i < static_cast<int64_t>(qb.size()); ++i) qb[i] = (i % (3 * C)) < 2 * C ? ud(rng) : vd(rng);
    a.q = qb.data(), a.k = qb.data() + C, a.v = qb.data() + 2 * C;
    a.q_ld = a.k_ld = a.v_ld = 3 * C;
    a.q_bs = a.k_bs = a.v_bs = c.lq * 3 * C;
  } else {  // separate buffers, rows padded by 3 floats, batches padded by 5 floats
    qb.resize(c.batch * (c.lq * (C + 3) + 5)), kb.resize(c.batch * (c.lk * (C + 3) + 5));
    vb.resize(kb.size());
    for (auto* buf : {&qb, &kb})
      for (float& x : *buf) x = ud(rng);
    for (float& x : vb) x = vd(rng);
    a.q = qb.data(), a.k = kb.data(), a.v = vb.data();
    a.q_ld = a.k_ld = a.v_ld = C + 3;
    a.q_bs = c.lq * (C + 3) + 5;
    a.k_bs = a.v_bs = c.lk * (C + 3) + 5;
  }
  const int64_t out_ld = C + 2;  // the 2 padding floats per row must stay untouched
  std::vector<float> out(c.batch * c.lq * out_ld, 12345.0f);
  a.out = out.data(), a.out_ld = out_ld, a.out_bs = c.lq * out_ld;
  attention(a);

  std::vector<double> s(c.lk);
  for (int64_t b = 0; b < c.batch; ++b)
    for (int64_t h = 0; h < c.heads; ++h)
      for (int64_t i = 0; i < c.lq; ++i) {
        const float* q = a.q + b * a.q_bs + i * a.q_ld + h * c.dh;
        const int64_t nk = c.causal ? i + 1 : c.lk;
        double mx = -INFINITY, smax = 0;
        for (int64_t j = 0; j < nk; ++j) {
          const float* k = a.k + b * a.k_bs + j * a.k_ld + h * c.dh;
          double dot = 0;
          for (int64_t d = 0; d < c.dh; ++d) dot += static_cast<double>(q[d]) * k[d];
          s[j] = dot * a.scale;
          mx = std::max(mx, s[j]);
          smax = std::max(smax, std::fabs(s[j]));
        }
        double sum = 0;
        for (int64_t j = 0; j < nk; ++j) sum += (s[j] = std::exp(s[j] - mx));
        for (int64_t d = 0; d < c.dh; ++d) {
          double ref = 0;
          for (int64_t j = 0; j < nk; ++j) ref += s[j] * a.v[b * a.v_bs + j * a.v_ld + h * c.dh + d];
          ref /= sum;
          const float got = out[b * a.out_bs + i * out_ld + h * c.dh + d];
          // float32 scores carry ~ulp(|s|) absolute error, which exp turns into relative error of p
          ASSERT_NEAR(got, ref, 2e-6 + 5e-7 * smax)
              << "b=" << b << " h=" << h << " i=" << i << " d=" << d;
        }
      }
  for (int64_t r = 0; r < c.batch * c.lq; ++r)
    for (int64_t p = C; p < out_ld; ++p) ASSERT_EQ(out[r * out_ld + p], 12345.0f) << "padding overwritten";
}

void check_both_paths(const Case& c) {
  for (KernelPath path : supported_kernel_paths()) {
    test::KernelPathGuard guard(path);
    SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " batch=" << c.batch << " heads="
                                    << c.heads << " lq=" << c.lq << " lk=" << c.lk << " dh=" << c.dh
                                    << (c.causal ? " causal" : "") << (c.fused ? " fused" : ""));
    check_case(c, 1234u + static_cast<uint32_t>(c.lq * 7 + c.lk * 3 + c.dh));
  }
}

TEST(Attention, TinyHeadsOddLengths) { check_both_paths({2, 3, 5, 7, 4}); }
TEST(Attention, SingleKey) { check_both_paths({2, 2, 3, 1, 8}); }
TEST(Attention, SingleQuerySingleKey) { check_both_paths({1, 1, 1, 1, 4}); }
TEST(Attention, CrossAttentionLqNotLk) { check_both_paths({1, 2, 100, 130, 64}); }
TEST(Attention, TileTailsAndOddHeadDim) { check_both_paths({2, 2, 65, 49, 20}); }
TEST(Attention, HeadDimNotMultipleOf8) { check_both_paths({1, 3, 17, 23, 12}); }
TEST(Attention, HeadDimOne) { check_both_paths({2, 3, 9, 10, 1}); }
TEST(Attention, HeadDim128) { check_both_paths({1, 2, 70, 33, 128}); }
TEST(Attention, VisionHeadDim80) { check_both_paths({1, 2, 257, 257, 80}); }
TEST(Attention, CausalText) { check_both_paths({1, 2, 77, 77, 64, true}); }
TEST(Attention, CausalAcrossTiles) { check_both_paths({2, 1, 150, 150, 8, true}); }
TEST(Attention, TemporalSixteenFrames) { check_both_paths({37, 2, 16, 16, 64}); }
TEST(Attention, OneFrame) { check_both_paths({5, 2, 1, 1, 64}); }
TEST(Attention, FusedQkvBuffer) { check_both_paths({2, 2, 70, 70, 16, false, true}); }
TEST(Attention, FusedQkvBufferCausal) { check_both_paths({1, 3, 33, 33, 8, true, true}); }
// The AVX-512 kernel's blocks: 12-key score rows (48-key tiles), 32- and 16-query columns, 64-channel P.V blocks
// with a masked last vector.
TEST(Attention, KeyRowTailsOfTwelve) { check_both_paths({1, 2, 45, 59, 64}); }   // 48 + 11 keys; 32 + 13 queries
TEST(Attention, SixteenQueryColumns) { check_both_paths({3, 1, 16, 21, 32}); }  // one 16-column block
TEST(Attention, HeadDimThreeVectors) { check_both_paths({1, 2, 33, 34, 48}); }
TEST(Attention, HeadDimOneFullBlockAndMaskedTail) { check_both_paths({1, 1, 19, 26, 97}); }  // 64 + 33
TEST(Attention, CausalThirtyTwoColumns) { check_both_paths({1, 2, 97, 97, 16, true}); }
TEST(Attention, LargeScoresAreStable) { check_both_paths({1, 2, 40, 90, 16, false, false, 20.0f}); }

// ---- Precision::Bf16 (attention.h) ---------------------------------------------------------------------------
// The reference computes the rule in double: q, k, v rounded to bfloat16, s = c q.k (c = scale log2 e), m = ceil of
// the row's max s, p = bf16(2^(s - m)), out = sum p v / sum p. The kernels' float32 scores differ from the double
// ones by up to dh ulps of sum |c q_d k_d|, and their exp2 by a few ulps: where 2^(s - m) lies that close to a
// midpoint between two bfloat16 values the kernel may round it the other way, so such weights (rare) are allowed
// one bfloat16 step (at most 2^-7 relative) either way. Every other weight must round as the reference does: a
// kernel that skipped rounding P, or the integral max, fails every case but the one-key ones.
void check_bf16_case(const Case& c, uint32_t seed) {
  const int64_t C = c.heads * c.dh;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ud(-c.amplitude, c.amplitude), vd(-1.0f, 1.0f);
  std::vector<float> qb(c.batch * c.lq * (C + 3)), kb(c.batch * c.lk * (C + 1)), vb(c.batch * c.lk * (C + 5));
  for (float& x : qb) x = ud(rng);
  for (float& x : kb) x = ud(rng);
  for (float& x : vb) x = vd(rng);
  AttentionArgs a;
  a.batch = c.batch, a.heads = c.heads, a.lq = c.lq, a.lk = c.lk, a.dh = c.dh, a.causal = c.causal;
  a.scale = 1.0f / std::sqrt(static_cast<float>(c.dh));
  a.q = qb.data(), a.q_ld = C + 3, a.q_bs = c.lq * (C + 3);
  a.k = kb.data(), a.k_ld = C + 1, a.k_bs = c.lk * (C + 1);
  a.v = vb.data(), a.v_ld = C + 5, a.v_bs = c.lk * (C + 5);
  std::vector<float> out(c.batch * c.lq * C, 12345.0f);
  a.out = out.data(), a.out_ld = C, a.out_bs = c.lq * C;
  attention(a);

  const double cl = double(a.scale) * 1.4426950408889634;  // as the kernels form it: float(scale), then log2 e
  const double step = std::ldexp(1.0, -7);                  // one bfloat16 step, relative (at most)
  std::vector<double> s(c.lk), p(c.lk), slack(c.lk);
  int64_t loose = 0, total = 0;
  for (int64_t b = 0; b < c.batch; ++b)
    for (int64_t h = 0; h < c.heads; ++h)
      for (int64_t i = 0; i < c.lq; ++i) {
        const int64_t nk = c.causal ? i + 1 : c.lk;
        double mx = -INFINITY;
        for (int64_t j = 0; j < nk; ++j) {
          double dot = 0, mag = 0;
          for (int64_t d = 0; d < c.dh; ++d) {
            const double t = test::round_bf16(a.q[b * a.q_bs + i * a.q_ld + h * c.dh + d]) *
                             test::round_bf16(a.k[b * a.k_bs + j * a.k_ld + h * c.dh + d]);
            dot += t, mag += std::fabs(t);
          }
          s[j] = cl * dot;
          // How far the kernel's exponent may stray: float32 sums of dh products and c, and exp2's few ulps.
          slack[j] = (double(c.dh) + 4.0) * test::kU * cl * mag + 8.0 * test::kU;
          mx = std::max(mx, s[j]);
        }
        const double m = std::ceil(mx);
        double sum = 0;
        for (int64_t j = 0; j < nk; ++j) {
          const double e = std::exp2(s[j] - m);
          p[j] = test::round_bf16(e);
          // A midpoint within reach: the kernel may round to the other neighbour.
          const double lo = test::round_bf16(e * (1 - 2 * slack[j])), hi = test::round_bf16(e * (1 + 2 * slack[j]));
          slack[j] = lo != hi ? step * p[j] : 0.0;
          loose += lo != hi, ++total;
          sum += p[j];
        }
        for (int64_t d = 0; d < c.dh; ++d) {
          double ref = 0, allow = 0, vmag = 0;
          double loose_sum = 0;
          for (int64_t j = 0; j < nk; ++j) {
            const double v = test::round_bf16(a.v[b * a.v_bs + j * a.v_ld + h * c.dh + d]);
            ref += p[j] * v, allow += slack[j] * std::fabs(v), vmag += p[j] * std::fabs(v), loose_sum += slack[j];
          }
          // A weight rounded the other way moves the numerator (by its step times v) and the sum (by its step,
          // times the output); then float32 accumulation of nk products and of the sum, and the division.
          const double rounding = (double(nk) + 8.0) * test::kU * 4.0 * vmag;
          const double tol = (allow + loose_sum * std::fabs(ref / sum) + rounding) / sum + 1e-7;
          const float got = out[b * a.out_bs + i * a.out_ld + h * c.dh + d];
          ASSERT_NEAR(got, ref / sum, tol) << "b=" << b << " h=" << h << " i=" << i << " d=" << d;
        }
      }
  // The allowance must stay an exception, or the test could not tell rounded weights from unrounded ones.
  EXPECT_LT(loose * 20, total + 20) << loose << " of " << total << " weights within reach of a rounding midpoint";
}

void check_bf16_paths(const Case& c) {
  const test::PrecisionGuard bf16(Precision::Bf16);
  for (KernelPath path : supported_kernel_paths())
    for (bool native : {true, false}) {
      if (!native && path != KernelPath::Avx512) continue;  // only avx512 has both
      test::KernelPathGuard guard(path);
      set_attention_bf16_native(native);
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << (native ? "" : " emulated") << " batch="
                                      << c.batch << " heads=" << c.heads << " lq=" << c.lq << " lk=" << c.lk
                                      << " dh=" << c.dh << (c.causal ? " causal" : ""));
      check_bf16_case(c, 99u + static_cast<uint32_t>(c.lq * 7 + c.lk * 3 + c.dh));
      set_attention_bf16_native(true);
    }
}

TEST(AttentionBf16, OddLengthsAndHeadDim) { check_bf16_paths({2, 3, 5, 7, 5}); }
TEST(AttentionBf16, SingleQuerySingleKey) { check_bf16_paths({1, 1, 1, 1, 4}); }
TEST(AttentionBf16, KeyTilesWithOddTail) { check_bf16_paths({1, 2, 70, 101, 64}); }  // 48 + 48 + 5 keys
TEST(AttentionBf16, QueryTilesAndColumnTails) { check_bf16_paths({2, 1, 145, 33, 32}); }  // 64 + 64 + 17
TEST(AttentionBf16, HeadDimTails) { check_bf16_paths({1, 2, 19, 26, 97}); }  // pairs 48 + 1, V rows of 112
TEST(AttentionBf16, Causal) { check_bf16_paths({1, 2, 150, 150, 16, true}); }
TEST(AttentionBf16, TemporalSixteenFrames) { check_bf16_paths({37, 2, 16, 16, 64}); }
TEST(AttentionBf16, OneFrame) { check_bf16_paths({5, 2, 1, 1, 64}); }
TEST(AttentionBf16, LargeScores) { check_bf16_paths({1, 2, 40, 90, 16, false, false, 6.0f}); }

TEST(Attention, RejectsCausalWithDifferentLengths) {
  std::vector<float> buf(64);
  AttentionArgs a;
  a.lq = 2, a.lk = 3, a.dh = 4, a.causal = true;
  a.q = a.k = a.v = buf.data(), a.out = buf.data();
  a.q_ld = a.k_ld = a.v_ld = a.out_ld = 4;
  EXPECT_THROW(attention(a), std::exception);
}

}  // namespace
}  // namespace egopd
