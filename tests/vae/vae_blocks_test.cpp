// VAE blocks against plain double-precision loops written here from vae.md / unet3d.md §3, on awkward shapes
// (odd sizes, one frame, several videos, pixel tiles with a tail, F16 weights).
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "core/dtype.h"
#include "core/safetensors.h"
#include "core/threading.h"
#include "core/weights.h"
#include "vae/vae_blocks.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;
using Vec = std::vector<double>;

// Random weights written to a safetensors file; `values` keeps what the file holds (rounded to F16 when asked).
struct TestWeights {
  std::map<std::string, Vec> values;
  std::vector<TensorToWrite> tensors;
  uint64_t state = 12345;
  DType dtype = DType::F32;

  double uniform() {  // [-1, 1)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return double(state >> 11) / 4503599627370496.0 - 1.0;
  }
  void add(const std::string& name, const Shape& shape, double lo, double amp) {
    Tensor t(shape);
    for (int64_t i = 0; i < t.numel(); ++i) t[i] = float(lo + amp * uniform());
    Vec v(size_t(t.numel()));
    for (int64_t i = 0; i < t.numel(); ++i)
      v[i] = dtype == DType::F16 ? half_to_float(float_to_half(t[i])) : t[i];
    values[name] = v;
    tensors.push_back(to_write(name, t, dtype));
  }
  void conv(const std::string& name, int64_t cout, int64_t cin, int64_t k) {
    add(name + ".weight", Shape{cout, cin, k, k}, 0, std::sqrt(3.0 / double(cin * k * k)));
    add(name + ".bias", Shape{cout}, 0, 0.2);
  }
  void tconv(const std::string& name, int64_t c) {
    add(name + ".weight", Shape{c, c, 3, 1, 1}, 0, std::sqrt(3.0 / double(c * 3)));
    add(name + ".bias", Shape{c}, 0, 0.2);
  }
  void norm(const std::string& name, int64_t c) {
    add(name + ".weight", Shape{c}, 1.0, 0.3);
    add(name + ".bias", Shape{c}, 0, 0.3);
  }
  void linear(const std::string& name, int64_t out, int64_t in) {
    add(name + ".weight", Shape{out, in}, 0, std::sqrt(3.0 / double(in)));
    add(name + ".bias", Shape{out}, 0, 0.2);
  }
  void resnet(const std::string& name, int64_t cin, int64_t cout) {
    norm(name + ".norm1", cin);
    conv(name + ".conv1", cout, cin, 3);
    norm(name + ".norm2", cout);
    conv(name + ".conv2", cout, cout, 3);
    if (cin != cout) conv(name + ".conv_shortcut", cout, cin, 1);
  }
  const Vec& operator()(const std::string& name) const { return values.at(name); }

  WeightMap load(const std::string& file_name) {
    const fs::path p = fs::temp_directory_path() / ("egopd_vae_blocks_" + std::to_string(::getpid()) + file_name);
    write_safetensors(p.string(), tensors);
    WeightMap m = WeightMap::load_file(p.string(), "vae");
    fs::remove(p);  // the mapping stays valid
    return m;
  }
};

Tensor random_tensor(const Shape& s, uint64_t seed, double amp = 1.0) {
  Tensor t(s);
  uint64_t st = seed;
  for (int64_t i = 0; i < t.numel(); ++i) {
    st = st * 6364136223846793005ull + 1442695040888963407ull;
    t[i] = float(amp * (double(st >> 11) / 4503599627370496.0 - 1.0));
  }
  return t;
}
Vec to_vec(const float* p, int64_t n) { return Vec(p, p + n); }

double silu(double v) { return v / (1.0 + std::exp(-v)); }

// GroupNorm(32) of `videos` blocks [frames, c, s]: statistics per (video, group) over frames x (c/32) x s values.
Vec ref_group_norm(const Vec& x, int64_t videos, int64_t frames, int64_t c, int64_t s, const Vec& gamma,
                   const Vec& beta, double eps, bool with_silu) {
  Vec y(x.size());
  const int64_t cg = c / 32;
  for (int64_t b = 0; b < videos; ++b)
    for (int64_t g = 0; g < 32; ++g) {
      double sum = 0, sq = 0, n = double(frames * cg * s);
      auto at = [&](int64_t f, int64_t ch, int64_t i) { return ((b * frames + f) * c + ch) * s + i; };
      for (int64_t f = 0; f < frames; ++f)
        for (int64_t ch = g * cg; ch < (g + 1) * cg; ++ch)
          for (int64_t i = 0; i < s; ++i) sum += x[at(f, ch, i)];
      const double mean = sum / n;
      for (int64_t f = 0; f < frames; ++f)
        for (int64_t ch = g * cg; ch < (g + 1) * cg; ++ch)
          for (int64_t i = 0; i < s; ++i) sq += (x[at(f, ch, i)] - mean) * (x[at(f, ch, i)] - mean);
      const double rstd = 1.0 / std::sqrt(sq / n + eps);
      for (int64_t f = 0; f < frames; ++f)
        for (int64_t ch = g * cg; ch < (g + 1) * cg; ++ch)
          for (int64_t i = 0; i < s; ++i) {
            const double v = (x[at(f, ch, i)] - mean) * rstd * gamma[ch] + beta[ch];
            y[at(f, ch, i)] = with_silu ? silu(v) : v;
          }
    }
  return y;
}

// One frame: x [cin, H, W] -> [cout, OH, OW], zero padding, cross-correlation.
Vec ref_conv2d(const Vec& x, int64_t cin, int64_t H, int64_t W, const Vec& w, const Vec& bias, int64_t cout, int64_t k,
               int64_t stride, int64_t pad, int64_t* oh_out = nullptr, int64_t* ow_out = nullptr) {
  const int64_t oh = (H + 2 * pad - k) / stride + 1, ow = (W + 2 * pad - k) / stride + 1;
  Vec y(size_t(cout * oh * ow));
  for (int64_t o = 0; o < cout; ++o)
    for (int64_t oy = 0; oy < oh; ++oy)
      for (int64_t ox = 0; ox < ow; ++ox) {
        double acc = bias[o];
        for (int64_t c = 0; c < cin; ++c)
          for (int64_t ky = 0; ky < k; ++ky)
            for (int64_t kx = 0; kx < k; ++kx) {
              const int64_t iy = oy * stride - pad + ky, ix = ox * stride - pad + kx;
              if (iy < 0 || iy >= H || ix < 0 || ix >= W) continue;
              acc += w[((o * cin + c) * k + ky) * k + kx] * x[(c * H + iy) * W + ix];
            }
        y[(o * oh + oy) * ow + ox] = acc;
      }
  if (oh_out) *oh_out = oh;
  if (ow_out) *ow_out = ow;
  return y;
}

// ResnetBlock2D without time embedding, one frame.
Vec ref_resnet(const TestWeights& tw, const std::string& p, const Vec& x, int64_t cin, int64_t cout, int64_t H,
               int64_t W, double eps) {
  const int64_t hw = H * W;
  Vec h = ref_group_norm(x, 1, 1, cin, hw, tw(p + ".norm1.weight"), tw(p + ".norm1.bias"), eps, true);
  h = ref_conv2d(h, cin, H, W, tw(p + ".conv1.weight"), tw(p + ".conv1.bias"), cout, 3, 1, 1);
  h = ref_group_norm(h, 1, 1, cout, hw, tw(p + ".norm2.weight"), tw(p + ".norm2.bias"), eps, true);
  h = ref_conv2d(h, cout, H, W, tw(p + ".conv2.weight"), tw(p + ".conv2.bias"), cout, 3, 1, 1);
  Vec s = cin != cout ? ref_conv2d(x, cin, H, W, tw(p + ".conv_shortcut.weight"), tw(p + ".conv_shortcut.bias"), cout,
                                   1, 1, 0)
                      : x;
  for (size_t i = 0; i < h.size(); ++i) h[i] += s[i];
  return h;
}

void expect_close(const float* got, const Vec& want, double tol, const std::string& what) {
  double worst = 0, scale = 0;
  for (size_t i = 0; i < want.size(); ++i) {
    worst = std::max(worst, std::abs(double(got[i]) - want[i]));
    scale = std::max(scale, std::abs(want[i]));
  }
  EXPECT_LE(worst, tol * std::max(1.0, scale)) << what << ": max abs error " << worst << " (max |ref| " << scale << ")";
}

TEST(VaeBlocks, ResnetBlock2DWithShortcutAndInPlace) {
  for (auto [cin, cout, H, W] : std::vector<std::array<int64_t, 4>>{{64, 96, 5, 7}, {64, 64, 1, 3}, {32, 32, 9, 4}}) {
    TestWeights tw;
    tw.resnet("r", cin, cout);
    WeightMap m = tw.load("resnet");
    ResnetBlock2D block(m.root().sub("r"), cin, cout, 1e-6f);
    Tensor x = random_tensor(Shape{cin, H, W}, 7 + cin + H);
    Vec want = ref_resnet(tw, "r", to_vec(x.data(), x.numel()), cin, cout, H, W, 1e-6);
    Tensor scratch(Shape{block.scratch_floats(H * W)});
    Tensor y(Shape{cout, H, W});
    block.forward_frame(x.data(), y.data(), H, W, scratch.data());
    expect_close(y.data(), want, 2e-5, "resnet " + std::to_string(cin) + "->" + std::to_string(cout));
    Tensor own = x.clone(), small(Shape{block.consuming_scratch_floats(H * W)}), y2(Shape{cout, H, W});
    block.forward_frame_consuming(own.data(), y2.data(), H, W, small.data());  // normalises its own copy in place
    expect_close(y2.data(), want, 2e-5, "resnet consuming its input");
    EXPECT_TRUE(std::equal(y2.data(), y2.data() + y2.numel(), y.data())) << "consuming call differs from forward_frame";
    if (cin == cout) {  // in place
      block.forward_frame(x.data(), x.data(), H, W, scratch.data());
      expect_close(x.data(), want, 2e-5, "resnet in place");
    }
  }
}

TEST(VaeBlocks, MidBlockAttentionOneHeadResidualF16) {
  const int64_t c = 64, H = 3, W = 5, hw = H * W;
  TestWeights tw;
  tw.dtype = DType::F16;
  tw.norm("a.group_norm", c);
  for (const char* l : {"a.to_q", "a.to_k", "a.to_v", "a.to_out.0"}) tw.linear(l, c, c);
  WeightMap m = tw.load("attn");
  MidBlockAttention attn(m.root().sub("a"), c);
  Tensor x = random_tensor(Shape{c, H, W}, 99, 2.0);
  Vec xv = to_vec(x.data(), x.numel());
  Vec n = ref_group_norm(xv, 1, 1, c, hw, tw("a.group_norm.weight"), tw("a.group_norm.bias"), 1e-6, false);
  auto lin = [&](const std::string& l, const Vec& t) {  // t [hw, c] -> [hw, c]
    Vec y(size_t(hw * c));
    for (int64_t i = 0; i < hw; ++i)
      for (int64_t o = 0; o < c; ++o) {
        double acc = tw(l + ".bias")[o];
        for (int64_t k = 0; k < c; ++k) acc += t[i * c + k] * tw(l + ".weight")[o * c + k];
        y[i * c + o] = acc;
      }
    return y;
  };
  Vec tok(size_t(hw * c));
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < hw; ++i) tok[i * c + ch] = n[ch * hw + i];
  Vec q = lin("a.to_q", tok), k = lin("a.to_k", tok), v = lin("a.to_v", tok), a(size_t(hw * c), 0.0);
  for (int64_t i = 0; i < hw; ++i) {
    Vec s(static_cast<size_t>(hw), 0.0);
    double mx = -1e300, sum = 0;
    for (int64_t j = 0; j < hw; ++j) {
      for (int64_t d = 0; d < c; ++d) s[j] += q[i * c + d] * k[j * c + d];
      s[j] /= std::sqrt(double(c));
      mx = std::max(mx, s[j]);
    }
    for (int64_t j = 0; j < hw; ++j) sum += (s[j] = std::exp(s[j] - mx));
    for (int64_t j = 0; j < hw; ++j)
      for (int64_t d = 0; d < c; ++d) a[i * c + d] += s[j] / sum * v[j * c + d];
  }
  Vec o = lin("a.to_out.0", a), want(xv);
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t i = 0; i < hw; ++i) want[ch * hw + i] += o[i * c + ch];
  Tensor scratch(Shape{attn.scratch_floats(hw)});
  attn.forward_frame(x.data(), hw, scratch.data());
  expect_close(x.data(), want, 2e-5, "mid-block attention");
}

TEST(VaeBlocks, EncoderDownsamplePadsRightAndBottomOnly) {
  const int64_t c = 32;
  for (auto [H, W] : std::vector<std::array<int64_t, 2>>{{7, 6}, {8, 8}, {3, 5}}) {
    TestWeights tw;
    tw.conv("d.conv", c, c, 3);
    WeightMap m = tw.load("down");
    EncoderDownsample down(m.root().sub("d"), c);
    Tensor x = random_tensor(Shape{c, H, W}, 5 + H * W);
    // reference: explicit [c, H+1, W+1] zero-padded copy, conv stride 2 padding 0
    Vec padded(size_t(c * (H + 1) * (W + 1)), 0.0);
    for (int64_t ch = 0; ch < c; ++ch)
      for (int64_t y = 0; y < H; ++y)
        for (int64_t xx = 0; xx < W; ++xx) padded[(ch * (H + 1) + y) * (W + 1) + xx] = x[(ch * H + y) * W + xx];
    int64_t oh = 0, ow = 0;
    Vec want = ref_conv2d(padded, c, H + 1, W + 1, tw("d.conv.weight"), tw("d.conv.bias"), c, 3, 2, 0, &oh, &ow);
    ASSERT_EQ(oh, EncoderDownsample::out_size(H));
    ASSERT_EQ(ow, EncoderDownsample::out_size(W));
    Tensor y(Shape{c, oh, ow}), scratch(Shape{down.scratch_floats(H, W)});
    down.forward_frame(x.data(), H, W, y.data(), scratch.data());
    expect_close(y.data(), want, 2e-5, "downsample " + std::to_string(H) + "x" + std::to_string(W));
  }
}

TEST(VaeBlocks, Upsample2xNearestThenConv) {
  const int64_t c = 32, H = 3, W = 5;
  TestWeights tw;
  tw.conv("u.conv", c, c, 3);
  WeightMap m = tw.load("up");
  Upsample2x up(m.root().sub("u"), c);
  Tensor x = random_tensor(Shape{c, H, W}, 17);
  Vec near(size_t(c * 4 * H * W));
  for (int64_t ch = 0; ch < c; ++ch)
    for (int64_t y = 0; y < 2 * H; ++y)
      for (int64_t xx = 0; xx < 2 * W; ++xx) near[(ch * 2 * H + y) * 2 * W + xx] = x[(ch * H + y / 2) * W + xx / 2];
  Vec want = ref_conv2d(near, c, 2 * H, 2 * W, tw("u.conv.weight"), tw("u.conv.bias"), c, 3, 1, 1);
  Tensor y(Shape{c, 2 * H, 2 * W}), scratch(Shape{up.scratch_floats(H, W)});
  up.forward_frame(x.data(), H, W, y.data(), scratch.data());
  expect_close(y.data(), want, 2e-5, "upsample");
}

// Decoder VaeSpatioTemporalResBlock: spatial ResnetBlock2D (eps 1e-6) per frame; per video a 5-D GroupNorm (eps 1e-5)
// over all frames, Conv3d (3,1,1) with zero time padding, twice; u = s + g; out = (1 − σ(m))·s + σ(m)·u.
Vec ref_spatio_temporal(const TestWeights& tw, const Vec& x, int64_t batch, int64_t frames, int64_t cin, int64_t cout,
                        int64_t H, int64_t W) {
  const int64_t n = batch * frames, hw = H * W;
  Vec s(size_t(n * cout * hw));
  for (int64_t f = 0; f < n; ++f) {
    Vec xf(x.begin() + f * cin * hw, x.begin() + (f + 1) * cin * hw);
    Vec sf = ref_resnet(tw, "b.spatial_res_block", xf, cin, cout, H, W, 1e-6);
    std::copy(sf.begin(), sf.end(), s.begin() + f * cout * hw);
  }
  const std::string t = "b.temporal_res_block";
  auto tconv = [&](const Vec& v, const std::string& name) {
    const Vec& w = tw(name + ".weight");
    const Vec& bias = tw(name + ".bias");
    Vec y(v.size());
    for (int64_t b = 0; b < batch; ++b)
      for (int64_t f = 0; f < frames; ++f)
        for (int64_t o = 0; o < cout; ++o)
          for (int64_t i = 0; i < hw; ++i) {
            double acc = bias[o];
            for (int64_t k = 0; k < 3; ++k) {
              const int64_t fs = f + k - 1;
              if (fs < 0 || fs >= frames) continue;
              for (int64_t c = 0; c < cout; ++c) acc += w[(o * cout + c) * 3 + k] * v[((b * frames + fs) * cout + c) * hw + i];
            }
            y[((b * frames + f) * cout + o) * hw + i] = acc;
          }
    return y;
  };
  Vec g = ref_group_norm(s, batch, frames, cout, hw, tw(t + ".norm1.weight"), tw(t + ".norm1.bias"), 1e-5, true);
  g = tconv(g, t + ".conv1");
  g = ref_group_norm(g, batch, frames, cout, hw, tw(t + ".norm2.weight"), tw(t + ".norm2.bias"), 1e-5, true);
  g = tconv(g, t + ".conv2");
  const double alpha = 1.0 / (1.0 + std::exp(-tw("b.time_mixer.mix_factor")[0]));
  Vec out(s.size());
  for (size_t i = 0; i < s.size(); ++i) out[i] = (1.0 - alpha) * s[i] + alpha * (s[i] + g[i]);
  return out;
}

TestWeights spatio_temporal_weights(int64_t cin, int64_t cout, bool with_upsampler) {
  TestWeights tw;
  tw.resnet("b.spatial_res_block", cin, cout);
  tw.norm("b.temporal_res_block.norm1", cout);
  tw.tconv("b.temporal_res_block.conv1", cout);
  tw.norm("b.temporal_res_block.norm2", cout);
  tw.tconv("b.temporal_res_block.conv2", cout);
  tw.add("b.time_mixer.mix_factor", Shape{1}, 0.3, 0.0);  // σ = 0.574: both branches matter
  if (with_upsampler) tw.conv("u.conv", cin, cin, 3);
  return tw;
}

struct StCase {
  int64_t batch, frames, cin, cout, H, W, tile_floats;
  bool recompute_conv1;
};

TEST(VaeBlocks, SpatioTemporalResBlockMatchesReference) {
  const std::vector<StCase> cases = {
      {1, 3, 64, 32, 3, 5, kDefaultTileFloats, false},  // width change (shortcut), one tile
      {2, 3, 32, 32, 3, 5, 32 * 3 * 4, false},          // two videos in place; tiles of 4 pixels with a tail of 3
      {1, 1, 32, 64, 2, 3, kDefaultTileFloats, false},  // a single frame: temporal taps at ±1 are padding
      {3, 2, 64, 64, 1, 7, 64 * 2 * 2, false},          // tiles of 2 pixels, odd width
      // low-memory mode: GroupNorm 2 statistics gathered tile by tile, conv1 recomputed for the output
      {1, 3, 64, 32, 3, 5, kDefaultTileFloats, true},  // one tile
      {2, 3, 32, 32, 3, 5, 32 * 3 * 4, true},          // tiles of 4 pixels with a tail of 3, two videos
      {1, 1, 32, 64, 2, 3, 1, true},                   // a single frame, one-pixel tiles
      {3, 2, 64, 64, 1, 7, 64 * 2 * 2, true},          // tiles of 2 pixels, odd width
  };
  for (const auto& k : cases) {
    TestWeights tw = spatio_temporal_weights(k.cin, k.cout, false);
    WeightMap m = tw.load("st");
    VaeSpatioTemporalResBlock block(m.root().sub("b"), k.cin, k.cout);
    const int64_t n = k.batch * k.frames;
    Tensor x = random_tensor(Shape{n, k.cin, k.H, k.W}, 3 + k.cin * k.frames);
    Vec want = ref_spatio_temporal(tw, to_vec(x.data(), x.numel()), k.batch, k.frames, k.cin, k.cout, k.H, k.W);
    Tensor y = block.forward(x.clone(), k.batch, k.frames, k.H, k.W, nullptr,
                             TemporalMemory{k.tile_floats, k.recompute_conv1});
    ASSERT_EQ(y.shape(), (Shape{n, k.cout, k.H, k.W}));
    expect_close(y.data(), want, 3e-5,
                 "st block b" + std::to_string(k.batch) + " f" + std::to_string(k.frames) + " tile " +
                     std::to_string(k.tile_floats) + (k.recompute_conv1 ? " recompute" : ""));
  }
}

TEST(VaeBlocks, SpatioTemporalResBlockWithFusedUpsampler) {
  const int64_t batch = 1, frames = 3, c = 32, h = 2, w = 3;
  for (auto [threads, co] : std::vector<std::pair<int, int64_t>>{{1, 32}, {2, 32}, {2, 64}}) {
    set_num_threads(threads);
    TestWeights tw = spatio_temporal_weights(c, co, true);
    WeightMap m = tw.load("st_up");
    VaeSpatioTemporalResBlock block(m.root().sub("b"), c, co);
    Upsample2x up(m.root().sub("u"), c);
    Tensor x = random_tensor(Shape{frames, c, h, w}, 41);
    Vec upsampled;  // reference input: every frame nearest x2 then conv
    for (int64_t f = 0; f < frames; ++f) {
      Vec near(size_t(c * 4 * h * w));
      for (int64_t ch = 0; ch < c; ++ch)
        for (int64_t y = 0; y < 2 * h; ++y)
          for (int64_t xx = 0; xx < 2 * w; ++xx)
            near[(ch * 2 * h + y) * 2 * w + xx] = x[((f * c + ch) * h + y / 2) * w + xx / 2];
      Vec uf = ref_conv2d(near, c, 2 * h, 2 * w, tw("u.conv.weight"), tw("u.conv.bias"), c, 3, 1, 1);
      upsampled.insert(upsampled.end(), uf.begin(), uf.end());
    }
    Vec want = ref_spatio_temporal(tw, upsampled, batch, frames, c, co, 2 * h, 2 * w);
    Tensor y = block.forward(x.clone(), batch, frames, 2 * h, 2 * w, &up);
    ASSERT_EQ(y.shape(), (Shape{frames, co, 2 * h, 2 * w}));
    expect_close(y.data(), want, 3e-5,
                 "st block with upsampler, threads " + std::to_string(threads) + ", cout " + std::to_string(co));
  }
  set_num_threads(0);
}

// With an upsampler the block writes a separate output and gives the pages of each consumed input frame back — but
// only when it holds the input's last reference: a caller's copy stays intact. Frames of 32 x 8 x 8 floats (8 KiB)
// span whole pages, so the discard really happens in the sole-owner run.
TEST(VaeBlocks, SpatioTemporalResBlockConsumesOnlyAnUnsharedInput) {
  const int64_t frames = 3, c = 32, h = 8, w = 8;
  TestWeights tw = spatio_temporal_weights(c, c, true);
  WeightMap m = tw.load("st_share");
  VaeSpatioTemporalResBlock block(m.root().sub("b"), c, c);
  Upsample2x up(m.root().sub("u"), c);
  Tensor x = random_tensor(Shape{frames, c, h, w}, 43);
  const Tensor original = x.clone();
  const Tensor shared = x;  // a second reference: forward must not consume the storage
  Tensor y_shared = block.forward(x, 1, frames, 2 * h, 2 * w, &up);
  EXPECT_TRUE(std::equal(shared.data(), shared.data() + shared.numel(), original.data()));
  Tensor y_sole = block.forward(x.clone(), 1, frames, 2 * h, 2 * w, &up);  // sole owner: input consumed
  EXPECT_TRUE(std::equal(y_sole.data(), y_sole.data() + y_sole.numel(), y_shared.data()));
}

}  // namespace
}  // namespace egopd
