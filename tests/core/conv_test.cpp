// conv2d and conv_temporal3 against double-precision direct loops, on every kernel path, with the direct algorithm
// (the Winograd one has its own test and bound: winograd_test.cpp).
// Tolerance: 2 (K + 3) u sum |w x| (+ bias / residual terms) + 8 u |ref|, u = 2^-24, K = taps summed, times 1.2
// when an activation follows.
#include <gtest/gtest.h>

#include "core/kernel_reference.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/kernels/conv.h"
#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"

namespace egopd {
namespace {

using test::act_ref;
using test::kU;
using test::round_bf16;
using test::random_vec;
using test::StoredWeight;

// Compares y against ref with per-element tolerances; returns the failure count.
int check(const std::vector<float>& y, const std::vector<double>& ref, const std::vector<double>& tol,
          const std::string& what) {
  int bad = 0;
  for (size_t i = 0; i < y.size(); ++i)
    if (!(std::fabs(y[i] - ref[i]) <= tol[i])) {
      if (bad < 3) ADD_FAILURE() << what << " at " << i << ": got " << y[i] << " want " << ref[i] << " tol " << tol[i];
      ++bad;
    }
  return bad;
}

struct ConvCase {
  int64_t n, cin, cout, h, w, k, stride, pad;
  DType dt = DType::F32;
  bool bias = true;
  Act act = Act::None;
  bool accumulate = false;
  bool bf16 = false;  // Precision::Bf16: the reference multiplies the weights and inputs rounded to bfloat16
  bool int8 = false;  // Precision::Int8: the float32 bound plus the quantisation bound of Int8Bound
  bool own_3x3 = false;  // call the kernel path's own 3x3 kernel (GemmPath::conv3x3_window) where it has one
};

// Precision::Int8 quantises each weight row and each input column (a pixel's receptive field) per K group with the
// scale max|v| / L of that group (L = 127 for the weights, A; int8_b_levels() for the inputs, B), so each value
// moves by at most half a step, at most max|v| / 2L over the whole row or column: |sum q_w q_x - sum w x| <=
// sum |w| X/2Lx + sum |x| W/254 + n W X/(254 * 2Lx) (W, X: the largest weight of the row and input of the column,
// n terms). A wrong scale, rounding or offset breaks it by whole steps.
struct Int8Bound {
  double sum_w = 0, sum_x = 0, max_x = 0;
  int64_t terms = 0;
  void add(double w, double x) {
    sum_w += std::fabs(w), sum_x += std::fabs(x), max_x = std::max(max_x, std::fabs(x)), ++terms;
  }
  double bound(double max_w) const {
    const double x_step = 2.0 * int8_b_levels();
    return sum_w * max_x / x_step + sum_x * max_w / 254.0 + double(terms) * max_w * max_x / (254.0 * x_step);
  }
};

// Largest magnitude of each of `rows` weight rows of length k.
std::vector<double> row_max(const std::vector<double>& w, int64_t rows, int64_t k) {
  std::vector<double> m(size_t(rows), 0.0);
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t i = 0; i < k; ++i) m[size_t(r)] = std::max(m[size_t(r)], std::fabs(w[size_t(r * k + i)]));
  return m;
}

int run_conv(const ConvCase& c, uint32_t seed) {
  std::mt19937 rng(seed);
  const Conv2dGeom g{c.cin, c.cout, c.k, c.k, c.stride, c.stride, c.pad, c.pad};
  const int64_t oh = g.out_h(c.h), ow = g.out_w(c.w), K = c.cin * c.k * c.k;
  const std::vector<float> x = random_vec(size_t(c.n * c.cin * c.h * c.w), rng);
  const StoredWeight wt(size_t(c.cout * K), c.dt, rng, size_t(K));
  const std::vector<float> bias = random_vec(size_t(c.cout), rng);
  std::vector<float> y = random_vec(size_t(c.n * c.cout * oh * ow), rng);
  const std::vector<float> y0 = y;
  {
    const test::PrecisionGuard precision(test::precision_of(c.bf16, c.int8));
    const auto own = c.own_3x3 ? gemm_detail::gemm_path().conv3x3_window : nullptr;
    if (own)  // conv2d takes it from 4096 pixels per call; these shapes are smaller
      EXPECT_TRUE(own(x.data(), c.n, c.h, c.w, wt.operand(K), c.bias ? bias.data() : nullptr, c.cin, c.cout, y.data(),
                      c.act, c.accumulate));
    else
      conv2d(x.data(), c.n, c.h, c.w, wt.operand(K), c.bias ? bias.data() : nullptr, g, y.data(), c.act, c.accumulate);
  }
  const auto w_at = [&](size_t i) { return c.bf16 ? round_bf16(wt.value[i]) : wt.value[i]; };
  const auto x_at = [&](size_t i) { return c.bf16 ? round_bf16(x[i]) : double(x[i]); };
  std::vector<double> ref(y.size()), tol(y.size());
  const std::vector<double> w_max = row_max(wt.value, c.cout, K);
  for (int64_t f = 0; f < c.n; ++f)
    for (int64_t o = 0; o < c.cout; ++o)
      for (int64_t oy = 0; oy < oh; ++oy)
        for (int64_t ox = 0; ox < ow; ++ox) {
          double s = c.bias ? bias[size_t(o)] : 0.0, sa = std::fabs(s);
          Int8Bound q8;
          for (int64_t ci = 0; ci < c.cin; ++ci)
            for (int64_t ky = 0; ky < c.k; ++ky)
              for (int64_t kx = 0; kx < c.k; ++kx) {
                const int64_t iy = oy * c.stride - c.pad + ky, ix = ox * c.stride - c.pad + kx;
                if (iy < 0 || iy >= c.h || ix < 0 || ix >= c.w) continue;
                const double wv = w_at(size_t(((o * c.cin + ci) * c.k + ky) * c.k + kx)),
                             xv = x_at(size_t(((f * c.cin + ci) * c.h + iy) * c.w + ix)), p = wv * xv;
                s += p;
                sa += std::fabs(p);
                q8.add(wv, xv);
              }
          const size_t idx = size_t(((f * c.cout + o) * oh + oy) * ow + ox);
          double r = act_ref(c.act, s);
          const double lip = c.act == Act::None ? 1.0 : 1.2;
          double t = lip * 2.0 * double(K + 3) * kU * sa + 8 * kU * std::fabs(r);
          if (c.int8) t += lip * q8.bound(w_max[size_t(o)]);
          if (c.accumulate) {
            r += y0[idx];
            t += 4 * kU * (std::fabs(y0[idx]) + std::fabs(r));
          }
          ref[idx] = r;
          tol[idx] = t + 1e-30;
        }
  return check(y, ref, tol,
               "conv " + std::to_string(c.k) + "x" + std::to_string(c.k) + "/" + std::to_string(c.stride) + " n" +
                   std::to_string(c.n) + " " + std::to_string(c.cin) + "->" + std::to_string(c.cout) + " " +
                   std::to_string(c.h) + "x" + std::to_string(c.w) + " " + dtype_name(c.dt) + (c.bf16 ? " bf16" : "") +
                   (c.int8 ? " int8" : ""));
}

struct TemporalCase {
  int64_t b, f, cin, cout, hw;
  DType dt = DType::F32;
  Act act = Act::None;
  bool accumulate = false;
  bool bf16 = false;
  bool int8 = false;
  int64_t y_stride = 0;  // floats between output rows (0: hw); the columns past hw must stay untouched
};

// Bᵀ, G and Aᵀ of Winograd F(m,3) (Lavin & Gray), m = 2 or 4: y = Aᵀ[(G w) ⊙ (Bᵀ d)].
struct TemporalWinogradMatrices {
  double bt[6][6], g[6][3], at[4][6];
};
const TemporalWinogradMatrices& temporal_matrices(int m) {
  static const TemporalWinogradMatrices f2{{{1, 0, -1, 0}, {0, 1, 1, 0}, {0, -1, 1, 0}, {0, 1, 0, -1}},
                                           {{1, 0, 0}, {0.5, 0.5, 0.5}, {0.5, -0.5, 0.5}, {0, 0, 1}},
                                           {{1, 1, 1, 0}, {0, 1, -1, -1}}};
  static const TemporalWinogradMatrices f4{
      {{4, 0, -5, 0, 1, 0}, {0, -4, -4, 1, 1, 0}, {0, 4, -4, -1, 1, 0}, {0, -2, -1, 2, 1, 0}, {0, 2, -1, -2, 1, 0},
       {0, 4, 0, -5, 0, 1}},
      {{0.25, 0, 0}, {-1.0 / 6, -1.0 / 6, -1.0 / 6}, {-1.0 / 6, 1.0 / 6, -1.0 / 6}, {1.0 / 24, 1.0 / 12, 1.0 / 6},
       {1.0 / 24, -1.0 / 12, 1.0 / 6}, {0, 0, 1}},
      {{1, 1, 1, 1, 1, 0}, {0, 1, -1, 2, -2, 0}, {0, 1, 1, 4, 4, 0}, {0, 1, -1, 8, -8, 1}}};
  return m == 2 ? f2 : f4;
}

int run_temporal(const TemporalCase& c, uint32_t seed) {
  std::mt19937 rng(seed);
  const std::vector<float> x = random_vec(size_t(c.b * c.f * c.cin * c.hw), rng);
  const StoredWeight wt(size_t(c.cout * c.cin * 3), c.dt, rng, size_t(c.cin * 3));  // [cout, cin, 3, 1, 1]
  const std::vector<float> bias = random_vec(size_t(c.cout), rng);
  const int64_t ys = c.y_stride > 0 ? c.y_stride : c.hw;
  std::vector<float> y = random_vec(size_t(c.b * c.f * c.cout * ys), rng);
  const std::vector<float> y0 = y;
  std::string algo;
  {
    const test::PrecisionGuard precision(test::precision_of(c.bf16, c.int8));
    algo = conv_temporal3_algorithm(c.f, c.cin, c.cout, c.hw);
    conv_temporal3(x.data(), c.b, c.f, c.cin, c.hw, wt.operand(c.cin * 3), bias.data(), c.cout, y.data(), c.act,
                   c.accumulate, c.y_stride);
  }
  const int tile = algo == "winograd F(2,3)" ? 2 : algo == "winograd F(4,3)" ? 4 : 0;
  if (!tile && algo != "direct") ADD_FAILURE() << "unknown temporal algorithm " << algo;
  const auto w_at = [&](size_t i) { return c.bf16 ? round_bf16(wt.value[i]) : wt.value[i]; };
  const auto x_at = [&](size_t i) { return c.bf16 ? round_bf16(x[i]) : double(x[i]); };
  std::vector<double> ref(y0.begin(), y0.end()), tol(y.size(), 0.0);  // the gaps between rows: exactly y0
  const std::vector<double> w_max = row_max(wt.value, c.cout, c.cin * 3);
  for (int64_t bi = 0; bi < c.b; ++bi)
    for (int64_t t = 0; t < c.f; ++t)
      for (int64_t o = 0; o < c.cout; ++o)
        for (int64_t p = 0; p < c.hw; ++p) {
          double s = bias[size_t(o)], sa = std::fabs(s);
          Int8Bound q8;
          for (int64_t ci = 0; ci < c.cin; ++ci)
            for (int64_t k = 0; k < 3; ++k) {
              const int64_t ts = t + k - 1;
              if (ts < 0 || ts >= c.f) continue;
              const double wv = w_at(size_t((o * c.cin + ci) * 3 + k)),
                           xv = x_at(size_t(((bi * c.f + ts) * c.cin + ci) * c.hw + p)), v = wv * xv;
              s += v;
              sa += std::fabs(v);
              q8.add(wv, xv);
            }
          const size_t idx = size_t(((bi * c.f + t) * c.cout + o) * ys + p);
          double r = act_ref(c.act, s);
          const double lip = c.act == Act::None ? 1.0 : 1.2;
          double tl = lip * 2.0 * double(3 * c.cin + 3) * kU * sa + 8 * kU * std::fabs(r);
          bool int8_bounded = false;  // Int8's bound already in tl
          if (tile && (c.bf16 || c.int8)) {
            // F(2,3) on bfloat16 operands, s = sum_i AT[r0][i] sum_c bf16(U_i) bf16(V_i); or on int8 ones, s the same
            // sums of float32 U_i V_i within the quantisation bound of each product (U_i quantised per output
            // channel, V_i per pixel, as the int8 GEMM quantises A and B).
            if (tile != 2) ADD_FAILURE() << "bf16 and int8 take F(2,3) only, not " << algo;
            const int64_t r0 = t % 2, t0 = t - r0 - 1;  // output r0 of its tile; d_k = x[t0 + k]
            const TemporalWinogradMatrices& T = temporal_matrices(2);
            const auto operand = [&](float v) { return c.bf16 ? round_bf16(v) : double(v); };
            s = bias[size_t(o)];
            double sw = 0;
            // The transforms in float32, as their one rounding each defines them (halving is exact).
            const auto filter_transform = [&](int64_t ci, float* u) {
              float w[3];
              for (int k = 0; k < 3; ++k) w[k] = float(wt.value[size_t((o * c.cin + ci) * 3 + k)]);
              const float h = 0.5f * (w[0] + w[2]);
              u[0] = w[0], u[1] = h + 0.5f * w[1], u[2] = h - 0.5f * w[1], u[3] = w[2];
            };
            Int8Bound wq8[4];
            double u_max[4] = {};  // of output channel o's U_i over all channels: at least each group's
            for (int64_t ci = 0; ci < c.cin; ++ci) {
              float u[4];
              filter_transform(ci, u);
              for (int i = 0; i < 4; ++i) u_max[i] = std::max(u_max[i], std::fabs(double(u[i])));
            }
            for (int64_t ci = 0; ci < c.cin; ++ci) {
              float d[4], u[4];
              for (int k = 0; k < 4; ++k) {
                const int64_t ts = t0 + k;
                d[k] = ts < 0 || ts >= c.f ? 0.0f : x[size_t(((bi * c.f + ts) * c.cin + ci) * c.hw + p)];
              }
              filter_transform(ci, u);
              const float v[4] = {d[0] - d[2], d[1] + d[2], d[2] - d[1], d[1] - d[3]};
              for (int i = 0; i < 4; ++i) {
                const double m = operand(u[i]) * operand(v[i]);
                s += T.at[r0][i] * m;
                sw += std::fabs(T.at[r0][i] * m);
                wq8[i].add(u[i], v[i]);
              }
            }
            r = act_ref(c.act, s);
            tl = lip * 2.0 * double(c.cin + 4) * kU * (sw + std::fabs(bias[size_t(o)])) + 8 * kU * std::fabs(r);
            if (c.int8) {
              for (int i = 0; i < 4; ++i) tl += lip * std::fabs(T.at[r0][i]) * wq8[i].bound(u_max[i]);
              int8_bounded = true;
            }
          } else if (tile) {  // Winograd F(m,3): the products |AT||G w||BT d| bound the float32 error
            const TemporalWinogradMatrices& T = temporal_matrices(tile);
            const int64_t r0 = t % tile, t0 = t - r0 - 1;  // output r0 of its tile; d_k = x[t0 + k]
            double sw = 0;
            for (int64_t ci = 0; ci < c.cin; ++ci) {
              double xa[6], wa[3];
              for (int k = 0; k < tile + 2; ++k) {
                const int64_t ts = t0 + k;
                xa[k] = ts < 0 || ts >= c.f ? 0.0 : std::fabs(x_at(size_t(((bi * c.f + ts) * c.cin + ci) * c.hw + p)));
              }
              for (int k = 0; k < 3; ++k) wa[k] = std::fabs(w_at(size_t((o * c.cin + ci) * 3 + k)));
              for (int i = 0; i < tile + 2; ++i) {
                double u = 0, v = 0;
                for (int k = 0; k < 3; ++k) u += std::fabs(T.g[i][k]) * wa[k];
                for (int k = 0; k < tile + 2; ++k) v += std::fabs(T.bt[i][k]) * xa[k];
                sw += std::fabs(T.at[r0][i]) * u * v;
              }
            }
            // cin additions of the products, and the rounding steps of the transforms (F(4,3): up to 4 in the input
            // and filter transforms each, 5 in the output transform)
            const double steps = double(c.cin) + (tile == 2 ? 8 : 14);
            tl = lip * 2.0 * steps * kU * (sw + std::fabs(bias[size_t(o)])) + 8 * kU * std::fabs(r);
          }
          if (c.int8 && !int8_bounded) tl += lip * q8.bound(w_max[size_t(o)]);
          if (c.accumulate) {
            r += y0[idx];
            tl += 4 * kU * (std::fabs(y0[idx]) + std::fabs(r));
          }
          ref[idx] = r;
          tol[idx] = tl + 1e-30;
        }
  return check(y, ref, tol,
               "temporal b" + std::to_string(c.b) + " f" + std::to_string(c.f) + " " + std::to_string(c.cin) + "->" +
                   std::to_string(c.cout) + " hw" + std::to_string(c.hw) + " " + dtype_name(c.dt));
}

// Puts back the temporal Winograd's tuning knobs that a test changes.
struct TemporalWinogradSettings {
  int64_t bytes = conv_detail::temporal_winograd_bytes();
  ~TemporalWinogradSettings() {
    conv_detail::temporal_winograd_bytes() = bytes;
    conv_detail::temporal_winograd_tile() = 0;
  }
};

class ConvTest : public test::KernelPathTest {
 protected:
  void SetUp() override {
    KernelPathTest::SetUp();
    set_conv_algo(ConvAlgo::Direct);
  }
  void TearDown() override {
    KernelPathTest::TearDown();
    set_conv_algo(algo_before_);
  }
  ConvAlgo algo_before_ = conv_algo();
};

TEST_P(ConvTest, Pointwise1x1) {
  EXPECT_EQ(run_conv({2, 5, 7, 3, 5, 1, 1, 0}, 1), 0);
  EXPECT_EQ(run_conv({1, 33, 20, 4, 8, 1, 1, 0}, 2), 0);  // hw = 32: full panels
  EXPECT_EQ(run_conv({3, 16, 6, 1, 1, 1, 1, 0}, 3), 0);   // 1x1 image
}

TEST_P(ConvTest, Same3x3) {
  EXPECT_EQ(run_conv({1, 3, 17, 7, 9, 3, 1, 1}, 10), 0);   // odd H/W, 1 frame
  EXPECT_EQ(run_conv({3, 16, 8, 5, 33, 3, 1, 1}, 11), 0);  // panels straddle rows, W > 16
  EXPECT_EQ(run_conv({2, 8, 6, 32, 32, 3, 1, 1}, 12), 0);  // panels inside rows
  EXPECT_EQ(run_conv({2, 50, 13, 6, 6, 3, 1, 1}, 13), 0);  // K = 450: several K passes on the L1-blocked paths
  const int64_t deep = gemm_detail::gemm_path().kc / 9 + 2;  // K = 9 * deep: two K passes on every path
  EXPECT_EQ(run_conv({1, deep, 7, 5, 6, 3, 1, 1}, 20), 0);
  EXPECT_EQ(run_conv({1, 4, 4, 1, 1, 3, 1, 1}, 14), 0);    // 1x1 image: only the centre tap
  EXPECT_EQ(run_conv({2, 4, 5, 2, 3, 3, 1, 1}, 15), 0);
  EXPECT_EQ(run_conv({3, 3, 7, 50, 50, 3, 1, 1}, 16), 0);  // column blocks end inside frames
  EXPECT_EQ(run_conv({1, 5, 60, 5, 7, 3, 1, 1}, 17), 0);    // cout > pixels: rows split across threads
  EXPECT_EQ(run_conv({2, 5, 8, 3, 8, 3, 1, 1}, 18), 0);    // 24 pixels: whole 12-column panels across rows
  EXPECT_EQ(run_conv({1, 3, 9, 4, 5, 3, 1, 1}, 19), 0);    // 20 pixels: a 12-column panel and a tail of 8
}

// Widths that are multiples of 16: on the avx512 path its own 3x3 kernel runs them (conv_internal.h,
// conv3x3_window_avx512, called directly: conv2d takes it from 4096 pixels per call), on the others conv2d's
// implicit GEMM; the same reference for both.
TEST_P(ConvTest, Same3x3WidthsOf16) {
  const auto own = [](ConvCase c) {
    c.own_3x3 = true;
    return c;
  };
  EXPECT_EQ(run_conv(own({1, 3, 5, 1, 16, 3, 1, 1}), 40), 0);     // one row: top and bottom taps outside; 16 pixels
  EXPECT_EQ(run_conv(own({2, 7, 13, 3, 16, 3, 1, 1}), 41), 0);    // 48 pixels: a tile across rows and a half tile
  EXPECT_EQ(run_conv(own({1, 40, 25, 5, 48, 3, 1, 1}), 42), 0);   // two K passes of 20 channels; a partial row panel
  EXPECT_EQ(run_conv(own({2, 70, 12, 4, 64, 3, 1, 1}), 43), 0);   // three K passes
  EXPECT_EQ(run_conv(own({1, 40, 60, 64, 48, 3, 1, 1}), 50), 0);  // two K passes in each of several blocks of tiles
  EXPECT_EQ(run_conv(own({1, 5, 7, 9, 32, 3, 1, 1}), 44), 0);     // odd height, one tile per row
  EXPECT_EQ(run_conv(own({2, 4, 12, 64, 128, 3, 1, 1}), 45), 0);  // 512 tiles: split across threads inside a frame
  EXPECT_EQ(run_conv(own({1, 2, 30, 3, 256, 3, 1, 1}), 46), 0);   // interior tiles with no masked lane
  for (DType dt : {DType::F16, DType::BF16, DType::I8})
    for (Act act : {Act::None, Act::SiLU})
      for (bool acc : {false, true}) {
        EXPECT_EQ(run_conv(own({2, 6, 11, 3, 32, 3, 1, 1, dt, true, act, acc}), 47), 0);
        ConvCase two_passes{1, 45, 7, 2, 16, 3, 1, 1, dt, act == Act::None, act, acc};
        two_passes.own_3x3 = true;  // the activation on the whole sum, then the residual
        EXPECT_EQ(run_conv(two_passes, 48), 0);
      }
}

// On the avx512 path, conv2d runs calls of 4096 pixels and more through its own 3x3 kernel: the same numbers as
// calling it directly.
TEST_P(ConvTest, WindowKernelIsWhatConv2dRuns) {
  const auto window = gemm_detail::gemm_path().conv3x3_window;
  if (GetParam() != KernelPath::Avx512) {
    EXPECT_EQ(window, nullptr);
    return;
  }
  ASSERT_NE(window, nullptr);
  std::mt19937 rng(49);
  const int64_t n = 2, cin = 40, cout = 14, h = 48, w = 48;  // 4608 pixels: conv2d takes it from 4096
  const std::vector<float> x = random_vec(size_t(n * cin * h * w), rng), bias = random_vec(size_t(cout), rng);
  const StoredWeight wt(size_t(cout * cin * 9), DType::F16, rng, size_t(cin * 9));
  std::vector<float> direct(size_t(n * cout * h * w)), via_conv2d(direct.size());
  ASSERT_TRUE(window(x.data(), n, h, w, wt.operand(cin * 9), bias.data(), cin, cout, direct.data(), Act::SiLU, false));
  conv2d(x.data(), n, h, w, wt.operand(cin * 9), bias.data(), Conv2dGeom{cin, cout, 3, 3, 1, 1, 1, 1},
         via_conv2d.data(), Act::SiLU);
  EXPECT_EQ(direct, via_conv2d);
  // What it leaves to the implicit GEMM: widths that are not multiples of 16.
  EXPECT_FALSE(window(x.data(), n, h, 40, wt.operand(cin * 9), nullptr, cin, cout, direct.data(), Act::None, false));
}

TEST_P(ConvTest, Strided3x3) {
  EXPECT_EQ(run_conv({1, 4, 5, 9, 11, 3, 2, 1}, 20), 0);
  EXPECT_EQ(run_conv({3, 7, 9, 8, 8, 3, 2, 1}, 21), 0);
  EXPECT_EQ(run_conv({2, 3, 4, 7, 7, 3, 1, 0}, 22), 0);  // valid padding: ow != w, general path
}

TEST_P(ConvTest, PatchEmbedding14x14) {
  EXPECT_EQ(run_conv({1, 3, 10, 28, 28, 14, 14, 0, DType::F32, false}, 30), 0);
  EXPECT_EQ(run_conv({2, 3, 17, 42, 28, 14, 14, 0, DType::F16, false}, 31), 0);
}

TEST_P(ConvTest, WeightDtypesAndEpilogues) {
  uint32_t seed = 40;
  for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8})
    for (Act act : {Act::None, Act::SiLU, Act::GELU})
      for (bool acc : {false, true}) {
        ConvCase c{2, 6, 11, 5, 7, 3, 1, 1, dt, true, act, acc};
        EXPECT_EQ(run_conv(c, seed++), 0);
        ConvCase big_k{1, 45, 7, 4, 4, 3, 1, 1, dt, true, act, acc};  // K = 405 > one K block
        EXPECT_EQ(run_conv(big_k, seed++), 0);
      }
}

// Frames narrower than a B panel share panels (gemm.cpp: merged segments): 7 frames of 6 pixels are 2-4 panels
// instead of 7 on every path; runs of one frame start and end inside panels. 1x1 and 3x3, several K passes, every
// epilogue (accumulate with an activation over several K passes goes through the engine's temporary first), and the
// reduced precisions, whose B scales are per column.
TEST_P(ConvTest, NarrowFramesShareBPanels) {
  uint32_t seed = 900;
  for (DType dt : {DType::F32, DType::F16, DType::I8})
    for (Act act : {Act::None, Act::SiLU})
      for (bool acc : {false, true}) {
        EXPECT_EQ(run_conv({7, 50, 13, 2, 3, 3, 1, 1, dt, true, act, acc}, seed++), 0);  // K = 450
        EXPECT_EQ(run_conv({7, 9, 30, 3, 2, 1, 1, 0, dt, act == Act::None, act, acc}, seed++), 0);
        EXPECT_EQ(run_conv({5, 11, 14, 4, 4, 3, 1, 1, dt, true, act, acc, act == Act::SiLU, act == Act::None}, seed++),
                  0);
      }
  for (int64_t f : {3, 16}) EXPECT_EQ(run_temporal({2, f, 40, 21, 5, DType::F16, Act::SiLU, true}, seed++), 0);
  EXPECT_EQ(run_temporal({2, 3, 9, 13, 5, DType::F32, Act::SiLU, true, false, false, 8}, seed++), 0);  // row stride 8
}

// Precision::Bf16 (3x3 convolutions then stay direct): 1x1, same and strided 3x3, patch embedding, temporal, every
// weight dtype, epilogues, one-frame clips, K over several passes; against a reference that rounds alike.
TEST_P(ConvTest, Bf16Compute) {
  uint32_t seed = 80;
  for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8}) {
    const ConvCase cases[] = {{2, 5, 7, 3, 5, 1, 1, 0, dt},          {1, 3, 17, 7, 9, 3, 1, 1, dt},
                              {2, 50, 13, 6, 6, 3, 1, 1, dt, true, Act::SiLU}, {1, 4, 4, 1, 1, 3, 1, 1, dt},
                              {3, 7, 9, 8, 8, 3, 2, 1, dt, true, Act::None, true}, {1, 3, 10, 28, 28, 14, 14, 0, dt}};
    for (ConvCase c : cases) {
      c.bf16 = true;
      EXPECT_EQ(run_conv(c, seed++), 0);
    }
    for (int64_t f : {1, 3}) {
      TemporalCase t{2, f, 9, 13, 37, dt};
      t.bf16 = true;
      EXPECT_EQ(run_temporal(t, seed++), 0);
    }
  }
}

// Precision::Bf16 with Winograd along time: F(2,3) whatever the tile asked for, its transformed filters and frames
// rounded to bfloat16 (the products' operands); frame counts with a partial last tile, pixel panel tails, odd
// channel counts (a half-empty last pair), every weight dtype, epilogues, K beyond a GEMM pass, one pixel panel per
// unit. Auto takes it from 256 input channels on (float32 from 16), and on AVX512-BF16 from 128 pixels per frame.
TEST_P(ConvTest, Bf16TemporalWinograd) {
  set_conv_algo(ConvAlgo::Winograd);
  const TemporalWinogradSettings restore;
  uint32_t seed = 900;
  const auto bf16 = [](TemporalCase t) { return t.bf16 = true, t; };
  for (int tile : {0, 4}) {
    conv_detail::temporal_winograd_tile() = tile;
    for (int64_t f : {2, 3, 16})
      for (int64_t hw : {1, 33}) EXPECT_EQ(run_temporal(bf16({2, f, 7, 5, hw}), seed++), 0);
  }
  conv_detail::temporal_winograd_tile() = 0;
  for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8})
    EXPECT_EQ(run_temporal(bf16({1, 5, 18, 13, 40, dt, Act::SiLU, true}), seed++), 0);
  EXPECT_EQ(run_temporal(bf16({1, 4, 701, 8, 40, DType::F16}), seed++), 0);  // cin > the GEMM's KC, odd
  EXPECT_EQ(run_temporal(bf16({2, 3, 20, 14, 70, DType::F16, Act::GELU, false, false, false, 100}), seed++), 0);
  conv_detail::temporal_winograd_bytes() = 1;
  EXPECT_EQ(run_temporal(bf16({2, 5, 9, 13, 150, DType::F32, Act::SiLU, true}), seed++), 0);
  conv_detail::temporal_winograd_bytes() = restore.bytes;
  set_conv_algo(ConvAlgo::Auto);
  const test::PrecisionGuard precision(Precision::Bf16);
  // 64 pixels per frame: direct where vdpbf16ps runs it (F(4,3) in float32).
  const bool native_bf16 = GetParam() == KernelPath::Avx512 && cpu_info().avx512_bf16;
  EXPECT_EQ(conv_temporal3_algorithm(16, 1280, 1280, 64), native_bf16 ? "direct" : "winograd F(2,3)");
  EXPECT_EQ(conv_temporal3_algorithm(16, 1280, 1280, 128), "winograd F(2,3)");
  EXPECT_EQ(conv_temporal3_algorithm(16, 1280, 1280, 16), "direct");
  EXPECT_EQ(conv_temporal3_algorithm(16, 256, 256, 1024), "winograd F(2,3)");
  EXPECT_EQ(conv_temporal3_algorithm(16, 128, 128, 2048), "direct");  // F(2,3) in float32
}

// Precision::Int8: the same cases within the quantisation bound (the 3x3 ones here direct, temporal ones direct or
// Winograd F(2,3)); and the result must differ from float32 (the operands really were quantised).
TEST_P(ConvTest, Int8Compute) {
  uint32_t seed = 180;
  for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8}) {
    const ConvCase cases[] = {{2, 5, 7, 3, 5, 1, 1, 0, dt},          {1, 3, 17, 7, 9, 3, 1, 1, dt},
                              {2, 50, 13, 6, 6, 3, 1, 1, dt, true, Act::SiLU}, {1, 4, 4, 1, 1, 3, 1, 1, dt},
                              {3, 7, 9, 8, 8, 3, 2, 1, dt, true, Act::None, true}, {1, 3, 10, 28, 28, 14, 14, 0, dt},
                              {1, 70, 9, 5, 6, 3, 1, 1, dt}};  // K = 630: two quantisation groups
    for (ConvCase c : cases) {
      c.int8 = true;
      EXPECT_EQ(run_conv(c, seed++), 0);
    }
    for (int64_t f : {1, 3}) {
      TemporalCase t{2, f, 9, 13, 37, dt};
      t.int8 = true;
      EXPECT_EQ(run_temporal(t, seed++), 0);
    }
    TemporalCase wide{1, 4, 200, 8, 20, dt};  // K = 600
    wide.int8 = true;
    EXPECT_EQ(run_temporal(wide, seed++), 0);
    // Winograd F(2,3) along time on quantised U_i and V_i (forced, and Auto: on 16+ channels and 32+ pixels where
    // the path takes it, GemmPath::i8_temporal_winograd, else direct): both tiles of a video of 5 frames whose last
    // tile is half past it, one and two videos, a residual with an activation, two quantisation groups (cin 600),
    // and a 16-frame clip.
    for (ConvAlgo algo : {ConvAlgo::Winograd, ConvAlgo::Auto}) {
      set_conv_algo(algo);
      for (TemporalCase w : {TemporalCase{2, 5, 20, 13, 37, dt}, TemporalCase{1, 16, 40, 8, 33, dt, Act::SiLU, true},
                             TemporalCase{1, 4, 600, 7, 40, dt}, TemporalCase{1, 2, 17, 6, 70, dt}}) {
        w.int8 = true;
        EXPECT_EQ(run_temporal(w, seed++), 0) << conv_algo_name(algo);
      }
    }
  }
  {
    const test::PrecisionGuard int8(Precision::Int8);
    EXPECT_EQ(conv_temporal3_algorithm(16, 320, 320, 1024),
              gemm_detail::gemm_path().i8_temporal_winograd ? "winograd F(2,3)" : "direct");
  }
  {  // forced Winograd on 1 to 3 input channels: the int8 panels' scales and sums need rows beyond cin
    set_conv_algo(ConvAlgo::Winograd);
    for (int64_t cin : {1, 2, 3}) {
      TemporalCase t{1, 3, cin, 5, 19};
      t.int8 = true;
      EXPECT_EQ(run_temporal(t, seed++), 0);
    }
    set_conv_algo(ConvAlgo::Auto);
  }
  std::mt19937 rng(5);
  const std::vector<float> x = random_vec(size_t(2 * 16 * 8 * 8), rng), w = random_vec(size_t(8 * 16 * 9), rng);
  const Conv2dGeom g{16, 8, 3, 3, 1, 1, 1, 1};
  std::vector<float> y32(size_t(2 * 8 * 8 * 8)), y8(y32.size());
  conv2d(x.data(), 2, 8, 8, f32_operand(w.data(), 16 * 9), nullptr, g, y32.data());
  {
    const test::PrecisionGuard int8(Precision::Int8);
    conv2d(x.data(), 2, 8, 8, f32_operand(w.data(), 16 * 9), nullptr, g, y8.data());
  }
  EXPECT_NE(y8, y32);
}

// Winograd F(2,3) and F(4,3) along time: frame counts that take each tile (2, 5: F(2,3); 3, 9, 16: F(4,3)) with
// the last tile partly past the video (5: one of two frames; 3, 9: three and one of four), one and two videos, pixel
// blocks and panel tails, every weight dtype, activations and residuals; Auto takes it on large layers only.
TEST_P(ConvTest, TemporalWinograd) {
  set_conv_algo(ConvAlgo::Winograd);
  const TemporalWinogradSettings restore;
  uint32_t seed = 700;
  for (int tile : {2, 4}) {
    conv_detail::temporal_winograd_tile() = tile;
    for (int64_t f : {2, 3, 5, 9, 16})
      for (int64_t hw : {1, 7, 33, 300}) {
        EXPECT_EQ(run_temporal({2, f, 6, 5, hw}, seed++), 0);
        EXPECT_EQ(run_temporal({1, f, 17, 13, hw, DType::F16}, seed++), 0);
      }
    EXPECT_EQ(run_temporal({1, 4, 700, 8, 40, DType::BF16}, seed++), 0);  // cin > the GEMM's KC
    EXPECT_EQ(run_temporal({2, 3, 20, 40, 70, DType::I8}, seed++), 0);
    EXPECT_EQ(run_temporal({2, 3, 7, 7, 9, DType::F32, Act::SiLU, true}, seed++), 0);
    EXPECT_EQ(run_temporal({1, 5, 30, 7, 65, DType::F16, Act::GELU, true}, seed++), 0);
    EXPECT_EQ(run_temporal({1, 1, 5, 4, 3, DType::F32, Act::None, true}, seed++), 0);  // one frame: centre tap
    for (int64_t f : {3, 4}) {  // rows of 70 pixels in a video of 100 (a tile of a larger frame)
      EXPECT_EQ(run_temporal({2, f, 20, 14, 70, DType::F16, Act::None, false, false, false, 100}, seed++), 0);
      EXPECT_EQ(run_temporal({1, f, 9, 13, 33, DType::F32, Act::SiLU, true, false, false, 40}, seed++), 0);
    }
    conv_detail::temporal_winograd_bytes() = 1;  // one pixel panel per unit of work (else up to 8), the last partial
    EXPECT_EQ(run_temporal({2, 5, 9, 13, 150, DType::F32, Act::SiLU, true}, seed++), 0);
    EXPECT_EQ(run_temporal({1, 4, 33, 40, 97, DType::F16}, seed++), 0);
    conv_detail::temporal_winograd_bytes() = restore.bytes;
  }
  conv_detail::temporal_winograd_tile() = 0;
  EXPECT_EQ(conv_temporal3_algorithm(1, 64, 64, 4096), "direct");
  EXPECT_EQ(conv_temporal3_algorithm(16, 256, 64, 4096), "winograd F(4,3)");  // 24 products against 32
  EXPECT_EQ(conv_temporal3_algorithm(2, 256, 64, 4096), "winograd F(2,3)");   // 4 against 6
  EXPECT_EQ(conv_temporal3_algorithm(3, 256, 64, 4096), "winograd F(4,3)");   // 6 against 8
  EXPECT_EQ(conv_temporal3_algorithm(5, 256, 64, 4096), "winograd F(2,3)");   // 12 each
  EXPECT_EQ(conv_temporal3_algorithm(16, 255, 64, 4096), "winograd F(2,3)");  // few channels: the transforms weigh
  set_conv_algo(ConvAlgo::Auto);
  EXPECT_EQ(conv_temporal3_algorithm(16, 128, 128, 65536), "winograd F(2,3)");  // the VAE decoder's top level
  EXPECT_EQ(conv_temporal3_algorithm(16, 1280, 1280, 64), "winograd F(4,3)");  // the U-Net's 8x8 frames
  EXPECT_EQ(conv_temporal3_algorithm(16, 1280, 1280, 16), "direct");           // its 4x4 frames: few pixels
  EXPECT_EQ(conv_temporal3_algorithm(16, 3, 128, 65536), "direct");              // few channels
  EXPECT_EQ(run_temporal({1, 16, 24, 20, 300, DType::F16}, seed++), 0);
  // auto's own choice at the U-Net's channel counts (F(4,3); 16 sampled output channels)
  for (int64_t cin : {320, 1280}) {
    ASSERT_EQ(conv_temporal3_algorithm(16, cin, 16, 40), "winograd F(4,3)");
    EXPECT_EQ(run_temporal({1, 16, cin, 16, 40, DType::F16}, seed++), 0);
  }
}

TEST_P(ConvTest, Temporal) {
  uint32_t seed = 60;
  for (int64_t f : {1, 2, 5})
    for (int64_t hw : {7, 16, 37}) {
      EXPECT_EQ(run_temporal({2, f, 6, 5, hw}, seed++), 0);
      EXPECT_EQ(run_temporal({2, f, 9, 13, hw, DType::F16}, seed++), 0);
    }
  EXPECT_EQ(run_temporal({1, 4, 150, 8, 20, DType::BF16}, seed++), 0);  // K = 450: taps split across K blocks
  EXPECT_EQ(run_temporal({2, 3, 20, 12, 10, DType::F32}, seed++), 0);    // full 6-row panels, 8-channel runs
  EXPECT_EQ(run_temporal({2, 3, 11, 7, 10, DType::I8}, seed++), 0);
  EXPECT_EQ(run_temporal({2, 3, 7, 7, 9, DType::F32, Act::SiLU, true}, seed++), 0);
  EXPECT_EQ(run_temporal({2, 3, 140, 7, 9, DType::F16, Act::GELU, true}, seed++), 0);
  EXPECT_EQ(run_temporal({1, 1, 5, 4, 3, DType::F32, Act::None, true}, seed++), 0);
  EXPECT_EQ(run_temporal({2, 3, 20, 14, 70, DType::F16, Act::None, false, false, false, 100}, seed++), 0);
  EXPECT_EQ(run_temporal({1, 5, 9, 13, 33, DType::F32, Act::SiLU, true, false, false, 40}, seed++), 0);
}

INSTANTIATE_TEST_SUITE_P(Paths, ConvTest, ::testing::ValuesIn(test::kAllKernelPaths),
                         test::kernel_path_test_name);

}  // namespace
}  // namespace egopd
