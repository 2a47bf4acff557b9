// Winograd convolutions F(2x2,3x3) and F(4x4,3x3) against a double-precision direct convolution, on every kernel
// path: odd and tiny frames (tile tails, frames smaller than a tile), several frames, channel counts that are not
// multiples of the register tiles, every weight dtype and epilogue, the models' real layer shapes, and the
// blocking (several output-channel and tile blocks, several K passes).
//
// Error bound. The computed result is y = Aᵀ[Σ_c (G g_c Gᵀ) ⊙ (Bᵀ d_c B)]A with every stage rounded. To first order
// in u = 2^-24 each stage's rounding error is at most (its rounding depth) * u times the same expression taken with
// absolute values of every matrix and operand, so
//     |y - y_exact| <= (n_G + n_B + 1 + cin + n_A) u W,   W = |Aᵀ|[Σ_c (|G||g_c||Gᵀ|) ⊙ (|Bᵀ||d_c||B|)]|A| + |bias|,
// where n_G <= 10 (two G stages, each a constant rounded to float, a product and two sums), n_B <= 6 and
// n_A <= 6 (two stages of at most three roundings: the constants are small integers), 1 for the product U ⊙ V and
// cin for the sum over input channels. W grows with the transform constants (F(4x4)'s 5, 8, 1/24 ...) and is
// exactly why F(4x4) is less accurate than F(2x2) and than the direct convolution (whose W is sum |w x|). The test
// asserts |y - ref| <= 2 (cin + 24) u W (+ 8 u |ref| and the activation / residual terms of conv_test.cpp), the
// factor 2 covering second-order terms. A wrong transform constant makes the error O(W): the test fails.
#include <gtest/gtest.h>

#include "core/kernel_reference.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd.h"
#include "core/kernels/winograd_internal.h"
#include "core/threading.h"

namespace egopd {
namespace {

using test::act_ref;
using test::kU;
using test::round_bf16;
using test::random_vec;
using test::StoredWeight;

// The transform matrices in double, for the bound only (the reference itself is the direct convolution).
struct Matrices {
  int m, a;
  std::vector<double> bt, g, at;  // Bᵀ [a][a], G [a][3], Aᵀ [m][a]
};

Matrices matrices(WinogradTile t) {
  if (t == WinogradTile::F2x2)
    return {2, 4,
            {1, 0, -1, 0, 0, 1, 1, 0, 0, -1, 1, 0, 0, 1, 0, -1},
            {1, 0, 0, .5, .5, .5, .5, -.5, .5, 0, 0, 1},
            {1, 1, 1, 0, 0, 1, -1, -1}};
  return {4, 6,
          {4, 0, -5, 0, 1, 0, 0, -4, -4, 1, 1, 0, 0, 4, -4, -1, 1, 0,
           0, -2, -1, 2, 1, 0, 0, 2, -1, -2, 1, 0, 0, 4, 0, -5, 0, 1},
          {1. / 4, 0, 0, -1. / 6, -1. / 6, -1. / 6, -1. / 6, 1. / 6, -1. / 6,
           1. / 24, 1. / 12, 1. / 6, 1. / 24, -1. / 12, 1. / 6, 0, 0, 1},
          {1, 1, 1, 1, 1, 0, 0, 1, -1, 2, -2, 0, 0, 1, 1, 4, 4, 0, 0, 1, -1, 8, -8, 1}};
}

// out[k][l] = sum_{r,s} |P[k][r]| |X[r][s]| |P[l][s]| for P [rows][cols] and X [cols][cols].
void abs_sandwich(const std::vector<double>& P, int rows, int cols, const double* X, double* out) {
  std::vector<double> t(size_t(cols * rows));
  for (int r = 0; r < cols; ++r)
    for (int l = 0; l < rows; ++l) {
      double s = 0;
      for (int q = 0; q < cols; ++q) s += std::fabs(X[r * cols + q]) * std::fabs(P[l * cols + q]);
      t[size_t(r * rows + l)] = s;
    }
  for (int k = 0; k < rows; ++k)
    for (int l = 0; l < rows; ++l) {
      double s = 0;
      for (int r = 0; r < cols; ++r) s += std::fabs(P[k * cols + r]) * t[size_t(r * rows + l)];
      out[k * rows + l] = s;
    }
}

struct WinoCase {
  int64_t n, cin, cout, h, w;
  DType dt = DType::F32;
  bool bias = true;
  Act act = Act::None;
  bool accumulate = false;
  bool bf16 = false;  // Precision::Bf16: the reference convolves the input and weights rounded to bfloat16
  bool int8 = false;  // Precision::Int8: the reference convolves them quantised (quantize_groups)
  // The first input channel and weight tap of every group but the first scaled by 64 (F32 weights): moving a group
  // boundary moves a spike into another group, or values into a spike's, and changes their quantisation steps.
  bool spike = false;
};

std::string describe(const WinoCase& c, WinogradTile t) {
  return std::string(winograd_tile_name(t)) + " n" + std::to_string(c.n) + " " + std::to_string(c.cin) + "->" +
         std::to_string(c.cout) + " " + std::to_string(c.h) + "x" + std::to_string(c.w) + " " + dtype_name(c.dt) +
         (c.bf16 ? " bf16" : "") + (c.int8 ? " int8" : "");
}

// The balanced groups of at most kInt8Block that split n values: their length (gemm.h, written out plainly).
int64_t group_length(int64_t n) {
  const int64_t groups = std::max<int64_t>(1, (n + kInt8Block - 1) / kInt8Block);
  return (n + groups - 1) / groups;
}

// Precision::Int8 on Winograd (winograd.h), written out plainly: the values v[at(l, k)] of each lane l, over each
// group of its k in [0, n), get m = max|v|, q = nearbyint(v * (127 / m)) in float32 clamped to +-127, and become
// q * m / 127 (zeros when m <= 1e-30).
template <class At>
void quantize_groups(std::vector<double>& v, int64_t lanes, int64_t n, At at) {
  const int64_t len = group_length(n);
  for (int64_t l = 0; l < lanes; ++l)
    for (int64_t k0 = 0; k0 < n; k0 += len) {
      const int64_t k1 = std::min(n, k0 + len);
      float m = 0.0f;
      for (int64_t k = k0; k < k1; ++k) m = std::max(m, std::fabs(float(v[at(l, k)])));
      const float inv = m > 1e-30f ? 127.0f / m : 0.0f;
      const double scale = m > 1e-30f ? double(m / 127.0f) : 0.0;
      for (int64_t k = k0; k < k1; ++k)
        v[at(l, k)] = double(std::clamp(std::nearbyint(float(v[at(l, k)]) * inv), -127.0f, 127.0f)) * scale;
    }
}

// The output channels checked: all of a small layer, else a spread over register tiles and blocks.
std::vector<int64_t> checked_channels(int64_t cout) {
  std::vector<int64_t> v;
  if (cout <= 16) {
    for (int64_t o = 0; o < cout; ++o) v.push_back(o);
    return v;
  }
  for (int64_t o : {int64_t(0), int64_t(5), int64_t(6), int64_t(11), int64_t(12), cout / 2 - 1, cout / 2 + 7,
                    cout - 2, cout - 1})
    if (std::find(v.begin(), v.end(), o) == v.end()) v.push_back(o);
  return v;
}

// One case's inputs, the exact outputs of the checked channels and their bound W (without the bias term).
struct Reference {
  WinoCase c;
  std::mt19937 rng;
  StoredWeight wt;
  std::vector<float> x, bias, y0;
  std::vector<double> xv, wv;  // the input and weight values convolved: x and wt.value, or those rounded (bf16)
  std::vector<int64_t> chans;
  std::vector<double> exact;  // [f][ci][h][w] over checked channels ci
  Reference(const WinoCase& c_, uint32_t seed)
      : c(c_), rng(seed), wt(size_t(c.cout * c.cin * 9), c.dt, rng, size_t(c.cin * 9)) {
    x = random_vec(size_t(c.n * c.cin * c.h * c.w), rng);
    bias = random_vec(size_t(c.cout), rng);
    y0 = random_vec(size_t(c.n * c.cout * c.h * c.w), rng);
    if (c.spike) {
      const int64_t hw = c.h * c.w, K = c.cin * 9, gx = group_length(c.cin), gw = group_length(K);
      for (size_t i = 0; i < x.size(); ++i)
        if (const int64_t ch = int64_t(i) / hw % c.cin; ch > 0 && ch % gx == 0) x[i] *= 64.0f;
      for (size_t i = 0; i < wt.f32.size(); ++i)
        if (const int64_t k = int64_t(i) % K; k > 0 && k % gw == 0) wt.value[i] = wt.f32[i] = 64.0f * wt.f32[i];
    }
    for (float v : x) xv.push_back(c.bf16 ? round_bf16(v) : v);
    for (double v : wt.value) wv.push_back(c.bf16 ? round_bf16(v) : v);
    if (c.int8) {
      const int64_t hw = c.h * c.w, K = c.cin * 9;
      // the input per pixel (frame f, pixel p: lane f * hw + p) over its channels; the weights per output channel
      // over its cin * 9 taps
      quantize_groups(xv, c.n * hw, c.cin, [&](int64_t l, int64_t ch) {
        return size_t((l / hw * c.cin + ch) * hw + l % hw);
      });
      quantize_groups(wv, c.cout, K, [&](int64_t o, int64_t k) { return size_t(o * K + k); });
    }
    chans = checked_channels(c.cout);
    compute_exact();
  }

  // exact from xv and wv (again after a test changes them).
  void compute_exact() {
    exact.assign(size_t(c.n) * chans.size() * size_t(c.h * c.w), 0.0);
    for (int64_t f = 0; f < c.n; ++f)
      for (size_t ci = 0; ci < chans.size(); ++ci)
        for (int64_t oy = 0; oy < c.h; ++oy)
          for (int64_t ox = 0; ox < c.w; ++ox) {
            double s = 0;
            for (int64_t i = 0; i < c.cin; ++i)
              for (int64_t ky = 0; ky < 3; ++ky)
                for (int64_t kx = 0; kx < 3; ++kx) {
                  const int64_t iy = oy + ky - 1, ix = ox + kx - 1;
                  if (iy < 0 || iy >= c.h || ix < 0 || ix >= c.w) continue;
                  s += wv[size_t(((chans[ci] * c.cin + i) * 3 + ky) * 3 + kx)] *
                       xv[size_t(((f * c.cin + i) * c.h + iy) * c.w + ix)];
                }
            exact[(size_t(f) * chans.size() + ci) * size_t(c.h * c.w) + size_t(oy * c.w + ox)] = s;
          }
  }

  // W of every checked output for tile t, same layout as exact.
  std::vector<double> bound(WinogradTile t) const {
    const Matrices mt = matrices(t);
    const int m = mt.m, a = mt.a, a2 = a * a;
    std::vector<double> gabs(chans.size() * size_t(c.cin * a2)), dabs(size_t(c.cin * a2)), W(exact.size());
    for (size_t ci = 0; ci < chans.size(); ++ci)
      for (int64_t i = 0; i < c.cin; ++i)
        abs_sandwich(mt.g, a, 3, &wv[size_t((chans[ci] * c.cin + i) * 9)],
                     &gabs[(ci * size_t(c.cin) + size_t(i)) * size_t(a2)]);
    std::vector<double> patch(static_cast<size_t>(a2)), s(static_cast<size_t>(a2));
    for (int64_t f = 0; f < c.n; ++f)
      for (int64_t ty = 0; ty * m < c.h; ++ty)
        for (int64_t tx = 0; tx * m < c.w; ++tx) {
          for (int64_t i = 0; i < c.cin; ++i) {
            for (int r = 0; r < a; ++r)
              for (int q = 0; q < a; ++q) {
                const int64_t iy = ty * m - 1 + r, ix = tx * m - 1 + q;
                const bool in = iy >= 0 && iy < c.h && ix >= 0 && ix < c.w;
                patch[size_t(r * a + q)] = in ? xv[size_t(((f * c.cin + i) * c.h + iy) * c.w + ix)] : 0.0;
              }
            abs_sandwich(mt.bt, a, a, patch.data(), &dabs[size_t(i * a2)]);
          }
          for (size_t ci = 0; ci < chans.size(); ++ci) {
            std::fill(s.begin(), s.end(), 0.0);
            for (int64_t i = 0; i < c.cin; ++i)
              for (int e = 0; e < a2; ++e)
                s[size_t(e)] += gabs[(ci * size_t(c.cin) + size_t(i)) * size_t(a2) + size_t(e)] * dabs[size_t(i * a2 + e)];
            for (int i = 0; i < m && ty * m + i < c.h; ++i)
              for (int j = 0; j < m && tx * m + j < c.w; ++j) {
                double v = 0;
                for (int k = 0; k < a; ++k)
                  for (int l = 0; l < a; ++l)
                    v += std::fabs(mt.at[size_t(i * a + k)]) * s[size_t(k * a + l)] * std::fabs(mt.at[size_t(j * a + l)]);
                W[(size_t(f) * chans.size() + ci) * size_t(c.h * c.w) + size_t((ty * m + i) * c.w + tx * m + j)] = v;
              }
          }
        }
    return W;
  }
};

// Runs `run` (which writes y) and checks the checked channels against the bound; returns the failure count and
// the largest error / tolerance ratio seen.
template <class Run>
int check_against(const Reference& R, WinogradTile t, Run run, double* worst_ratio = nullptr) {
  const WinoCase& c = R.c;
  std::vector<float> y = R.y0;
  run(y);
  const std::vector<double> W = R.bound(t);
  const double gamma = 2.0 * double(c.cin + 24) * kU;
  int bad = 0;
  double worst = 0;
  const int64_t hw = c.h * c.w;
  for (int64_t f = 0; f < c.n; ++f)
    for (size_t ci = 0; ci < R.chans.size(); ++ci)
      for (int64_t p = 0; p < hw; ++p) {
        const int64_t o = R.chans[ci];
        const size_t ri = (size_t(f) * R.chans.size() + ci) * size_t(hw) + size_t(p);
        const size_t yi = size_t((f * c.cout + o) * hw + p);
        const double b = c.bias ? R.bias[size_t(o)] : 0.0;
        double ref = act_ref(c.act, R.exact[ri] + b);
        double tol = (c.act == Act::None ? 1.0 : 1.2) * gamma * (W[ri] + std::fabs(b)) + 8 * kU * std::fabs(ref);
        if (c.accumulate) {
          ref += R.y0[yi];
          tol += 4 * kU * (std::fabs(R.y0[yi]) + std::fabs(ref));
        }
        tol += 1e-30;
        const double err = std::fabs(double(y[yi]) - ref);
        worst = std::max(worst, err / tol);
        if (!(err <= tol)) {
          if (bad < 3)
            ADD_FAILURE() << describe(c, t) << " frame " << f << " channel " << o << " pixel " << p << ": got "
                          << y[yi] << " want " << ref << " tol " << tol;
          ++bad;
        }
      }
  if (worst_ratio) *worst_ratio = worst;
  return bad;
}

int run_wino(const WinoCase& c, WinogradTile t, uint32_t seed) {
  const Reference R(c, seed);
  return check_against(R, t, [&](std::vector<float>& y) {
    const test::PrecisionGuard precision(test::precision_of(c.bf16, c.int8));
    conv2d_winograd(R.x.data(), c.n, c.h, c.w, R.wt.operand(c.cin * 9), c.bias ? R.bias.data() : nullptr, c.cin,
                    c.cout, y.data(), c.act, c.accumulate, t);
  });
}

class WinogradTest : public test::KernelPathTest {
 protected:
  void TearDown() override {
    KernelPathTest::TearDown();
    set_conv_algo(algo_before_);
  }
  ConvAlgo algo_before_ = conv_algo();
};

constexpr WinogradTile kTiles[] = {WinogradTile::F2x2, WinogradTile::F4x4};

TEST_P(WinogradTest, OddAndTinyFrames) {
  uint32_t seed = 1;
  for (WinogradTile t : kTiles) {
    EXPECT_EQ(run_wino({1, 5, 7, 1, 1}, t, seed++), 0);     // 1x1 frame: one tile, all padding but the centre
    EXPECT_EQ(run_wino({2, 3, 9, 3, 5}, t, seed++), 0);     // smaller than / one tile wide
    EXPECT_EQ(run_wino({1, 13, 17, 7, 9}, t, seed++), 0);   // odd: partial tiles on both edges
    EXPECT_EQ(run_wino({3, 17, 13, 17, 13}, t, seed++), 0); // several frames; panels across tile rows and frames
    EXPECT_EQ(run_wino({2, 16, 6, 5, 33}, t, seed++), 0);   // wide, panels inside one tile row
    EXPECT_EQ(run_wino({1, 1, 1, 2, 2}, t, seed++), 0);     // one channel
    EXPECT_EQ(run_wino({4, 7, 25, 12, 10}, t, seed++), 0);  // sizes not multiple of the tile
    EXPECT_EQ(run_wino({1, 4, 3, 40, 3}, t, seed++), 0);    // tall and narrow
    EXPECT_EQ(run_wino({1, 5, 3, 6, 301}, t, seed++), 0);   // rows wider than a panel: panels start inside them
    EXPECT_EQ(run_wino({1, 3, 2, 8, 62}, t, seed++), 0);    // a row of 16 tiles, 32 with the next: the last
    EXPECT_EQ(run_wino({1, 3, 2, 5, 126}, t, seed++), 0);   // column of a half-panel is padding
  }
}

TEST_P(WinogradTest, ChannelTailsAndBlocking) {
  uint32_t seed = 20;
  for (WinogradTile t : kTiles) {
    const int cin = int(gemm_detail::gemm_path().kc) + 5;
    EXPECT_EQ(run_wino({1, cin, 14, 6, 7}, t, seed++), 0);   // cin > KC: two K passes
    EXPECT_EQ(run_wino({1, 9, 200, 5, 5}, t, seed++), 0);    // cout over several row chunks, not a multiple of MR
    EXPECT_EQ(run_wino({2, 33, 19, 9, 11}, t, seed++), 0);   // cin not a multiple of the lanes
  }
}

// Restores the Winograd scratch budgets and the default thread count when a blocking test ends.
struct BlockingRestore {
  wino_detail::WinogradBudgets saved = wino_detail::winograd_budgets();
  ~BlockingRestore() {
    wino_detail::winograd_budgets() = saved;
    set_num_threads(0);
  }
};

// Several blocks of output channels and of tiles, on small shapes under shrunken scratch budgets: both orders of
// the two block loops and the one-block-of-all-tiles case are reached (asserted on the blocking the driver uses)
// and checked against the reference.
TEST_P(WinogradTest, EveryBlockingOrder) {
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  const int MR = path.mr, L = path.nr;
  const BlockingRestore restore;
  wino_detail::WinogradBudgets& budget = wino_detail::winograd_budgets();
  uint32_t seed = 90;
  for (WinogradTile t : kTiles) {
    const int64_t m = t == WinogradTile::F4x4 ? 4 : 2, a2 = (m + 2) * (m + 2);
    const int64_t n = 2, cin = 20, h = 11 * m, w = 6 * m + 1, ntiles = n * 11 * 7;  // partial tiles on the right
    budget.tiles = 1;  // one panel of tiles per block
    budget.min_block_tiles = 1;
    budget.whole_tiles = 0;
    budget.whole_filter = 0;
    // Blocks of more than L output channels: output-channel blocks outside, V recomputed for each.
    budget.filter = a2 * cin * 4 * 3 * L;
    int64_t cout = 6 * L + 5;
    wino_detail::WinogradBlocking b = wino_detail::winograd_blocking(cin, cout, ntiles, a2, MR, L, num_threads());
    ASSERT_TRUE(b.ncb > 1 && b.ntb > 1 && !b.tiles_outside) << b.ncb << " " << b.ntb;
    EXPECT_EQ(run_wino({n, cin, cout, h, w}, t, seed++), 0);
    // The same with room for the U of all output channels: one block of them, V transformed once per tile block.
    budget.whole_filter = a2 * cin * 4 * (cout + MR);
    b = wino_detail::winograd_blocking(cin, cout, ntiles, a2, MR, L, num_threads());
    ASSERT_TRUE(b.ncb == 1 && b.ntb > 1) << b.ncb << " " << b.ntb;
    EXPECT_EQ(run_wino({n, cin, cout, h, w}, t, seed++), 0);
    budget.whole_filter = 0;
    // Blocks of MR (< L) output channels: tile blocks outside, U recomputed for each.
    budget.filter = a2 * cin * 4 * MR;
    cout = 3 * MR + 1;
    b = wino_detail::winograd_blocking(cin, cout, ntiles, a2, MR, L, num_threads());
    ASSERT_TRUE(b.ncb > 1 && b.ntb > 1 && b.tiles_outside) << b.ncb << " " << b.ntb;
    EXPECT_EQ(run_wino({n, cin, cout, h, w}, t, seed++), 0);
    // All tiles in one block, shared by the blocks of output channels.
    budget.whole_tiles = int64_t(1) << 40;
    b = wino_detail::winograd_blocking(cin, cout, ntiles, a2, MR, L, num_threads());
    ASSERT_TRUE(b.ncb > 1 && b.ntb == 1) << b.ncb << " " << b.ntb;
    EXPECT_EQ(run_wino({n, cin, cout, h, w}, t, seed++), 0);
  }
  // The smaller U block (budget.filter_near) where V's per-position slice fits in 3/4 of L2, budget.filter where it
  // does not.
  budget = wino_detail::WinogradBudgets{};
  const int64_t l2 = cpu_info().l2_bytes(), a2 = 36, cin = 64, cout = 8 * MR;
  budget.filter = a2 * cin * 4 * cout;  // every output channel in one block
  budget.filter_near = a2 * cin * 4 * 2 * MR;
  budget.min_block_tiles = L;
  budget.tiles = budget.whole_tiles = a2 * (cin + cout) * 4 * 4 * L;  // blocks of four panels of tiles
  ASSERT_LE(4 * L * cin * 4, l2 * 3 / 4);
  wino_detail::WinogradBlocking b = wino_detail::winograd_blocking(cin, cout, 4 * L, a2, MR, L, 1);
  EXPECT_EQ(b.co, 2 * MR);
  EXPECT_EQ(run_wino({1, cin, cout, 8 * 4, L}, WinogradTile::F4x4, seed++), 0);  // 8 x L/4 tiles of 4x4: 2 L
  const int64_t wide = l2 / (cin * 4) / L * L + L;  // tiles whose slice exceeds 3/4 of L2 in one block
  budget.tiles = budget.whole_tiles = int64_t(1) << 40;
  b = wino_detail::winograd_blocking(cin, cout, wide, a2, MR, L, 1);
  EXPECT_EQ(b.co, cout);
}

// Two threads, U transformed for each of several blocks of output channels: blocks of a multiple of 2 x MR rows,
// each thread's own half of a block in every phase. The block count is the plan's or up to twice it, whichever pads
// cout least; in a last block that ends inside the first thread's half, the second multiplies no padding panels.
TEST_P(WinogradTest, OwnRowsBlocks) {
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  const int MR = path.mr, L = path.nr;
  const BlockingRestore restore;
  wino_detail::WinogradBudgets& budget = wino_detail::winograd_budgets();
  const int64_t a2 = 36, cin = 20, ntiles = 2 * 11 * 7;
  // 640 output channels in blocks of at most 108 (9 panels of 12): 6 of 120 rows, 720 in all, or 9 of 72, 648.
  budget.filter = budget.filter_near = a2 * cin * 4 * 108;
  budget.whole_filter = 0;
  wino_detail::WinogradBlocking b = wino_detail::winograd_blocking(cin, 640, ntiles, a2, 12, 32, 1);
  EXPECT_TRUE(b.co == 108 && b.ncb == 6 && !b.own_rows) << b.co << " " << b.ncb;
  b = wino_detail::winograd_blocking(cin, 640, ntiles, a2, 12, 32, 2);
  EXPECT_TRUE(b.co == 72 && b.ncb == 9 && b.own_rows) << b.co << " " << b.ncb;
  // One block of all output channels: no rows of a thread's own.
  budget.filter = budget.filter_near = a2 * cin * 4 * 648;
  EXPECT_FALSE(wino_detail::winograd_blocking(cin, 640, ntiles, a2, 12, 32, 2).own_rows);

  // On this path's panels: 3 units of 2 x MR rows and one more in blocks of half of that, so two blocks of two units;
  // the last holds one unit and a row, the second thread's half of it one row and MR - 1 padding rows.
  set_num_threads(2);
  const int64_t unit = 2 * MR, cout = 3 * unit + 1;
  uint32_t seed = 140;
  for (WinogradTile t : kTiles) {
    const int64_t m = t == WinogradTile::F4x4 ? 4 : 2, tile_a2 = (m + 2) * (m + 2);
    budget.filter = budget.filter_near = tile_a2 * cin * 4 * ((cout + 1) / 2 + MR - 1) / MR * MR;
    b = wino_detail::winograd_blocking(cin, cout, ntiles, tile_a2, MR, L, 2);
    ASSERT_TRUE(b.own_rows && b.ncb == 2 && b.co == 2 * unit) << b.co << " " << b.ncb;
    EXPECT_EQ(run_wino({2, cin, cout, 11 * m, 6 * m + 1}, t, seed++), 0);  // 2 x 11 x 7 tiles, as ntiles
  }
}

TEST_P(WinogradTest, WeightDtypesAndEpilogues) {
  uint32_t seed = 40;
  for (WinogradTile t : kTiles)
    for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8})
      for (Act act : {Act::None, Act::SiLU, Act::GELU, Act::QuickGELU})
        for (bool acc : {false, true}) {
          EXPECT_EQ(run_wino({2, 19, 21, 9, 7, dt, true, act, acc}, t, seed++), 0);
          EXPECT_EQ(run_wino({1, 6, 5, 4, 5, dt, false, act, acc}, t, seed++), 0);
        }
}

// Precision::Bf16: the input values and the weights are rounded to bfloat16, the transforms and products stay
// float32, so the result is the float32-Winograd convolution of the rounded operands (the reference convolves those
// exactly, under the float32 bound: without the rounding the error is ~2^-9 relative, far outside it). Every weight
// dtype, tails of panels and channels, epilogues; and conv2d's dispatch under bf16 (auto and forced Winograd).
TEST_P(WinogradTest, Bf16RoundsTheInputsThenTransformsInFloat32) {
  uint32_t seed = 90;
  for (WinogradTile t : kTiles)
    for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8}) {
      EXPECT_EQ(run_wino({2, 19, 21, 9, 7, dt, true, Act::None, false, true}, t, seed++), 0);
      EXPECT_EQ(run_wino({1, 40, 30, 12, 70, dt, true, Act::SiLU, true, true}, t, seed++), 0);
    }
  // Frames of at least 16 pixels: auto's bf16 F(4x4) keeps to those where vdpbf16ps runs (GemmPath).
  const WinoCase c{4, 24, 20, 17, 19, DType::F16, true, Act::None, false, true};
  const Reference R(c, 99);
  const Conv2dGeom g{c.cin, c.cout, 3, 3, 1, 1, 1, 1};
  for (ConvAlgo algo : {ConvAlgo::Winograd, ConvAlgo::Auto}) {
    set_conv_algo(algo);
    {
      const test::PrecisionGuard bf16(Precision::Bf16);
      const WinogradTile t = winograd_tile_for(c.h, c.w);
      EXPECT_EQ(conv2d_algorithm(g, c.n, c.h, c.w), std::string("winograd ") + winograd_tile_name(t));
      EXPECT_EQ(check_against(R, t, [&](std::vector<float>& y) {
                  conv2d(R.x.data(), c.n, c.h, c.w, R.wt.operand(c.cin * 9), R.bias.data(), g, y.data());
                }),
                0)
          << conv_algo_name(algo);
    }
  }
}

// Precision::Int8: the input quantised per pixel and group of channels, the weights per output channel and group
// of taps, both to 127 levels on every path, then float32 Winograd: the reference convolves the quantised values
// exactly, under the float32 bound (a wrong scale or group moves values by whole quantisation steps, ~1e-2 relative,
// far outside it). Two groups of channels and eleven of taps (cin = 600: groups of 300 channels, of 491 taps that
// split input channels; once with spikes at the groups' starts, so that their scales differ), odd sizes, one frame, tile tails, rows past cout, every weight dtype, epilogues; and
// conv2d's dispatch under int8.
TEST_P(WinogradTest, Int8QuantisesThenTransformsInFloat32) {
  uint32_t seed = 150;
  for (WinogradTile t : kTiles) {
    for (DType dt : {DType::F32, DType::F16, DType::BF16, DType::I8}) {
      EXPECT_EQ(run_wino({2, 19, 21, 9, 7, dt, true, Act::None, false, false, true}, t, seed++), 0);
      EXPECT_EQ(run_wino({1, 40, 30, 12, 70, dt, true, Act::SiLU, true, false, true}, t, seed++), 0);
    }
    EXPECT_EQ(run_wino({1, 5, 7, 1, 1, DType::F32, true, Act::None, false, false, true}, t, seed++), 0);
    EXPECT_EQ(run_wino({3, 17, 13, 17, 13, DType::F16, false, Act::None, false, false, true}, t, seed++), 0);
    EXPECT_EQ(run_wino({1, 9, 200, 5, 5, DType::F16, true, Act::GELU, false, false, true}, t, seed++), 0);
    EXPECT_EQ(run_wino({1, 600, 14, 6, 7, DType::F16, true, Act::None, true, false, true}, t, seed++), 0);
    EXPECT_EQ(run_wino({2, 600, 13, 5, 9, DType::F32, true, Act::None, false, false, true, true}, t, seed++), 0);
  }
  // A frame of zeros but one pixel: every other pixel's scale is 0 and quantises to zeros.
  {
    const WinoCase c{1, 8, 6, 8, 8, DType::F32, true, Act::None, false, false, true};
    Reference R(c, seed++);
    std::fill(R.x.begin(), R.x.end(), 0.0f);
    R.x[size_t(3 * 64 + 27)] = 0.75f;
    std::fill(R.xv.begin(), R.xv.end(), 0.0);
    R.xv[size_t(3 * 64 + 27)] = 0.75;  // its own maximum: exact
    R.compute_exact();
    EXPECT_EQ(check_against(R, WinogradTile::F4x4, [&](std::vector<float>& y) {
                const test::PrecisionGuard int8(Precision::Int8);
                conv2d_winograd(R.x.data(), c.n, c.h, c.w, R.wt.operand(c.cin * 9), R.bias.data(), c.cin, c.cout,
                                y.data(), c.act, c.accumulate, WinogradTile::F4x4);
              }),
              0);
  }
  // conv2d: forced Winograd always; auto where Winograd wins in float32 and the frames are at least the path's
  // GemmPath::i8_winograd_min_frame (on the others the int8 direct convolution is faster).
  const WinoCase c{16, 24, 20, 17, 18, DType::F16, true, Act::None, false, false, true};
  const Reference R(c, 199);
  const Conv2dGeom g{c.cin, c.cout, 3, 3, 1, 1, 1, 1};
  const test::PrecisionGuard int8(Precision::Int8);
  const int64_t min_frame = gemm_detail::gemm_path().i8_winograd_min_frame;
  for (ConvAlgo algo : {ConvAlgo::Winograd, ConvAlgo::Auto}) {
    set_conv_algo(algo);
    const bool winograd = algo == ConvAlgo::Winograd || min_frame <= 17;
    EXPECT_EQ(conv2d_algorithm(g, c.n, c.h, c.w), winograd ? "winograd F(4x4,3x3)" : "direct") << conv_algo_name(algo);
    if (winograd) {
      EXPECT_EQ(check_against(R, WinogradTile::F4x4, [&](std::vector<float>& y) {
                  conv2d(R.x.data(), c.n, c.h, c.w, R.wt.operand(c.cin * 9), R.bias.data(), g, y.data());
                }),
                0)
          << conv_algo_name(algo);
    }
  }
  set_conv_algo(ConvAlgo::Auto);
  if (min_frame > 0 && min_frame < 4096) {
    EXPECT_EQ(conv2d_algorithm(g, 16, min_frame - 1, 64), "direct");
    EXPECT_NE(conv2d_algorithm(g, 16, min_frame, 64), "direct");
  }
  set_conv_algo(ConvAlgo::Direct);
  EXPECT_EQ(conv2d_algorithm(g, c.n, c.h, c.w), "direct");
}

// conv2d takes Winograd when told to (and for 3x3 stride-1 pad-1 only); Auto takes it on large layers.
TEST_P(WinogradTest, Conv2dDispatch) {
  const WinoCase c{16, 24, 20, 11, 13, DType::F16};
  const Reference R(c, 60);
  const Conv2dGeom g{c.cin, c.cout, 3, 3, 1, 1, 1, 1};
  for (ConvAlgo algo : {ConvAlgo::Winograd, ConvAlgo::Auto}) {
    set_conv_algo(algo);
    ASSERT_TRUE(algo == ConvAlgo::Winograd || winograd_wins(c.cin, c.cout, c.n, c.h, c.w));
    EXPECT_EQ(check_against(R, winograd_tile_for(c.h, c.w), [&](std::vector<float>& y) {
                conv2d(R.x.data(), c.n, c.h, c.w, R.wt.operand(c.cin * 9), R.bias.data(), g, y.data());
              }),
              0)
        << conv_algo_name(algo);
  }
  EXPECT_FALSE(winograd_wins(3, 128, 16, 256, 256));  // the VAE's 3-channel output: direct
  EXPECT_FALSE(winograd_wins(1280, 1280, 4, 8, 8));    // 8x8 frames, few of them: direct
  EXPECT_TRUE(winograd_wins(1280, 1280, 8, 8, 8));
  // 4x4 frames (F(2x2)): the path's number of pixels in all needed (float32: 256 on avx2 and avx512, else 1024;
  // bf16: 1024 where vdpbf16ps runs the direct convolution, else as float32).
  const bool x86 = GetParam() == KernelPath::Avx2 || GetParam() == KernelPath::Avx512;
  const bool native_bf16 = GetParam() == KernelPath::Avx512 && cpu_info().avx512_bf16;
  for (Precision p : {Precision::Fp32, Precision::Bf16}) {
    const test::PrecisionGuard guard(p);
    const int64_t f2_pixels = x86 && !(p == Precision::Bf16 && native_bf16) ? 256 : 1024;
    EXPECT_FALSE(winograd_wins(1280, 1280, f2_pixels / 16 - 1, 4, 4)) << precision_name(p);
    EXPECT_TRUE(winograd_wins(1280, 1280, f2_pixels / 16, 4, 4)) << precision_name(p);
    EXPECT_TRUE(winograd_wins(1280, 1280, 64, 4, 4)) << precision_name(p);
    // F(4x4) under bf16 with vdpbf16ps: frames under 16 pixels take the direct convolution.
    const bool f4_small = !(p == Precision::Bf16 && native_bf16);
    EXPECT_EQ(winograd_wins(1280, 1280, 16, 8, 8), f4_small) << precision_name(p);
    EXPECT_EQ(winograd_wins(1280, 1280, 16, 15, 40), f4_small) << precision_name(p);
    EXPECT_TRUE(winograd_wins(1280, 1280, 16, 16, 16)) << precision_name(p);
  }
  EXPECT_TRUE(winograd_wins(512, 512, 1, 64, 64));
  EXPECT_EQ(winograd_tile_for(4, 4), WinogradTile::F2x2);
  EXPECT_EQ(winograd_tile_for(3, 40), WinogradTile::F2x2);
  EXPECT_EQ(winograd_tile_for(8, 9), WinogradTile::F4x4);
}

INSTANTIATE_TEST_SUITE_P(Paths, WinogradTest, ::testing::ValuesIn(test::kAllKernelPaths),
                         test::kernel_path_test_name);

// The models' layer shapes (one frame, F16 weights as stored; sampled output channels), every supported path, the
// tile each would use and F(2x2); prints the largest error / tolerance ratio seen.
TEST(WinogradRealShapes, UNetAndVaeLevels) {
  const struct {
    const char* what;
    int64_t ch, size;
  } shapes[] = {{"unet", 320, 32}, {"unet", 640, 16}, {"unet", 1280, 8}, {"unet", 1280, 4},
                {"vae", 128, 256}, {"vae", 256, 128}, {"vae", 512, 64},  {"vae", 512, 32}};
  uint32_t seed = 80;
  const test::KernelPathGuard restore(kernel_path());
  for (const auto& s : shapes) {
    const WinoCase c{1, s.ch, s.ch, s.size, s.size, DType::F16};
    const Reference R(c, seed++);
    for (KernelPath p : supported_kernel_paths()) {
      set_kernel_path(p);
      for (WinogradTile t : {winograd_tile_for(s.size, s.size), WinogradTile::F2x2}) {
        double worst = 0;
        EXPECT_EQ(check_against(R, t, [&](std::vector<float>& y) {
                    conv2d_winograd(R.x.data(), 1, c.h, c.w, R.wt.operand(c.cin * 9), R.bias.data(), c.cin, c.cout,
                                    y.data(), Act::None, false, t);
                  }, &worst),
                  0)
            << s.what << " " << describe(c, t) << " on " << kernel_path_name(p);
        std::printf("%s %s on %s: largest error / tolerance %.3g\n", s.what, describe(c, t).c_str(),
                    kernel_path_name(p), worst);
        if (t == WinogradTile::F2x2 && winograd_tile_for(s.size, s.size) == WinogradTile::F2x2) break;
      }
    }
  }
}

}  // namespace
}  // namespace egopd
