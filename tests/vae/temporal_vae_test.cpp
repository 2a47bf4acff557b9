// TemporalVAE as a whole: parameter tree and strict loading, golden cases, chunked decoding (vae.md §5.2), scaling.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/golden.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "core/threading.h"
#include "reused_blocks.h"
#include "vae/temporal_vae.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;

std::string golden(const std::string& name) { return (fs::path(EGOPD_TEST_DATA) / "data" / "golden" / name).string(); }

struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& tag)
      : path(fs::temp_directory_path() / ("egopd_vae_" + tag + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
  std::string str() const { return path.string(); }
};

Tensor random_tensor(const Shape& s, uint64_t seed) {
  Tensor t(s);
  uint64_t st = seed;
  for (int64_t i = 0; i < t.numel(); ++i) {
    st = st * 6364136223846793005ull + 1442695040888963407ull;
    t[i] = float(double(st >> 11) / 4503599627370496.0 - 1.0);
  }
  return t;
}

Tensor rows(const Tensor& t, int64_t r0, int64_t n) {
  const int64_t row = t.numel() / t.dim(0);
  Tensor out(Shape{n, t.dim(1), t.dim(2), t.dim(3)});
  std::copy(t.data() + r0 * row, t.data() + (r0 + n) * row, out.data());
  return out;
}

double max_diff(const float* a, const float* b, int64_t n) {
  double m = 0;
  for (int64_t i = 0; i < n; ++i) m = std::max(m, std::abs(double(a[i]) - double(b[i])));
  return m;
}

// A tiny model: two levels, 32/64 channels, one res-block per down block (two per decoder up block).
VaeConfig tiny_config() {
  VaeConfig c;
  c.block_out_channels = {32, 64};
  c.layers_per_block = 1;
  return c;
}

// Writes config + weights for `cfg` from the parameter list, letting `edit` drop/reshape/add entries.
void write_model(const std::string& dir, const VaeConfig& cfg,
                 const std::function<void(std::vector<std::pair<std::string, Shape>>&)>& edit) {
  write_file_atomic((fs::path(dir) / "config.json").string(), dump_json(cfg.to_json()));
  auto params = vae_parameter_shapes(cfg);
  edit(params);
  std::vector<TensorToWrite> w;
  for (const auto& [name, shape] : params) w.push_back(to_write(name, Tensor::full(shape, 0.01f)));
  write_safetensors((fs::path(dir) / "diffusion_pytorch_model.safetensors").string(), w);
}

std::string load_error(const std::string& dir) {
  try {
    TemporalVAE vae(dir);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(TemporalVae, SvdXtParameterTree) {
  int64_t total = 0, mixers = 0;
  for (const auto& [name, shape] : vae_parameter_shapes(VaeConfig::svd_xt())) {
    total += shape.numel();
    mixers += name.find("time_mixer.mix_factor") != std::string::npos;
  }
  EXPECT_EQ(total, 97742847);  // vae.md §1
  EXPECT_EQ(mixers, 14);       // vae.md §6
  // work counted from the architecture, near the figures (4,376 and 12,112 GFLOP for 16 frames at 256x256)
  EXPECT_NEAR(vae_encode_flop(VaeConfig::svd_xt(), 16, 256, 256) / 1e9, 4376.0, 0.01 * 4376.0);
  EXPECT_NEAR(vae_decode_flop(VaeConfig::svd_xt(), 16, 32, 32) / 1e9, 12112.0, 0.01 * 12112.0);
}

TEST(TemporalVae, ParameterTreeMatchesWhatTheModelLoads) {
  // the full list loads (nothing missing, nothing unexpected) and the model runs end to end
  TempDir dir("complete");
  write_model(dir.str(), tiny_config(), [](auto&) {});
  TemporalVAE vae(dir.str());
  EXPECT_EQ(vae.config().block_out_channels, (std::vector<int64_t>{32, 64}));
  EXPECT_FLOAT_EQ(vae.scaling_factor(), 0.18215f);
  Tensor mean = vae.encode_mean(random_tensor(Shape{2, 3, 8, 6}, 1));
  ASSERT_EQ(mean.shape(), (Shape{2, 4, 4, 3}));
  Tensor y = vae.decode(mean, 2);
  ASSERT_EQ(y.shape(), (Shape{2, 3, 8, 6}));
  for (int64_t i = 0; i < y.numel(); ++i) ASSERT_TRUE(std::isfinite(y[i]));
}

TEST(TemporalVae, LoadErrorsNameTheKey) {
  const VaeConfig cfg = tiny_config();
  const std::string key = "decoder.up_blocks.1.resnets.0.spatial_res_block.conv_shortcut.weight";
  {
    TempDir dir("missing");
    write_model(dir.str(), cfg, [&](auto& p) {
      std::erase_if(p, [&](const auto& e) { return e.first == key; });
    });
    const std::string msg = load_error(dir.str());
    EXPECT_NE(msg.find(key), std::string::npos) << msg;
    EXPECT_NE(msg.find("missing"), std::string::npos) << msg;
  }
  {
    TempDir dir("misshaped");
    const std::string k2 = "decoder.mid_block.resnets.0.temporal_res_block.conv1.weight";
    write_model(dir.str(), cfg, [&](auto& p) {
      for (auto& e : p)
        if (e.first == k2) e.second = Shape{64, 64, 3, 3};
    });
    const std::string msg = load_error(dir.str());
    EXPECT_NE(msg.find(k2), std::string::npos) << msg;
    EXPECT_NE(msg.find("[64,64,3,3]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("[64,64,3,1,1]"), std::string::npos) << msg;
  }
  {
    TempDir dir("unexpected");
    const std::string extra = "decoder.up_blocks.0.resnets.3.time_mixer.mix_factor";
    write_model(dir.str(), cfg, [&](auto& p) { p.push_back({extra, Shape{1}}); });
    const std::string msg = load_error(dir.str());
    EXPECT_NE(msg.find(extra), std::string::npos) << msg;
    EXPECT_NE(msg.find("unexpected"), std::string::npos) << msg;
  }
  {
    TempDir dir("badconfig");
    VaeConfig bad = cfg;
    bad.block_out_channels = {32, 48};
    write_model(dir.str(), bad, [](auto&) {});
    const std::string msg = load_error(dir.str());
    EXPECT_NE(msg.find("block_out_channels"), std::string::npos) << msg;
  }
}

void expect_golden(const std::string& name, const CaseOutputs& out) {
  GoldenCase c = load_golden_case(golden(name));
  for (const auto& r : compare_case_outputs(c, out))
    EXPECT_TRUE(r.ok) << name << ": " << r.name << " max_abs " << r.max_abs << " (tol " << r.tol_max_abs << ") rel_l2 "
                      << r.rel_l2 << " (tol " << r.tol_rel_l2 << ") " << r.message;
}

TEST(TemporalVae, GoldenEncodeAndDecode) {
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    {
      GoldenCase c = load_golden_case(golden("vae_encode"));
      TemporalVAE vae(c.model_dir());
      CaseOutputs out;
      Tensor logvar;
      out.tensors["latent_mean"] = vae.encode_mean(c.input("image"), &logvar);
      out.tensors["latent_logvar"] = logvar;
      expect_golden("vae_encode", out);
    }
    {
      GoldenCase c = load_golden_case(golden("vae_decode"));
      TemporalVAE vae(c.model_dir());
      CaseOutputs out;
      out.tensors["sample"] = vae.decode_frames(c.input("z"), c.args.get_int("num_frames"));
      expect_golden("vae_decode", out);
      // the whole clip as one chunk (the runtime default) is the same call
      out.tensors["sample"] = vae.decode(c.input("z"), c.args.get_int("num_frames"));
      expect_golden("vae_decode", out);
    }
  }
  set_num_threads(0);
}

// Reused activation blocks hold old values (here NaN bits, reused_blocks.h): the decoder must write every
// block before it reads it. 4 frames of 64x64 x 32 channels make its whole-clip tensors 2 MiB, large enough to be
// cached. The decoded clip must be bit for bit the one decoded in fresh memory.
TEST(TemporalVae, DecoderWritesReusedBlocksBeforeReadingThem) {
  TemporalVAE vae(load_golden_case(golden("vae_decode")).model_dir());
  const Tensor z = random_tensor(Shape{4, 4, 32, 32}, 11);
  const auto run = testing_memory::run_in_fresh_and_poisoned_blocks([&] { return vae.decode(z, 4); });
  EXPECT_GT(run.hits, 3u);  // the decode really ran in poisoned blocks
  EXPECT_EQ(run.differing, 0) << "of " << run.fresh.numel();
}

TEST(TemporalVae, EncoderIsPerFrameAndTakesOddSizes) {
  TemporalVAE vae(load_golden_case(golden("vae_encode")).model_dir());
  Tensor images = random_tensor(Shape{3, 3, 13, 10}, 5);
  Tensor logvar;
  Tensor mean = vae.encode_mean(images, &logvar);
  ASSERT_EQ(mean.shape(), (Shape{3, 4, 6, 5}));  // one downsampling: (13+1-3)/2+1 = 6, (10+1-3)/2+1 = 5
  Tensor one = vae.encode_mean(rows(images, 1, 1));
  EXPECT_LE(max_diff(one.data(), mean.data() + one.numel(), one.numel()), 1e-6);
  for (int64_t i = 0; i < logvar.numel(); ++i) {
    EXPECT_GE(logvar[i], -30.0f);
    EXPECT_LE(logvar[i], 20.0f);
  }
  EXPECT_THROW(vae.encode_mean(Tensor::zeros(Shape{1, 4, 8, 8})), Error);
}

// vae.md §5.2: each chunk of rows is decoded as one sequence, so the temporal layers couple exactly the frames of a
// chunk; chunk = F decodes each video alone (= the decoder called with num_frames = F).
TEST(TemporalVae, ChunkedDecodingCouplesFramesWithinAChunkOnly) {
  TemporalVAE vae(load_golden_case(golden("vae_decode")).model_dir());
  const int64_t F = 3, B = 2, n = B * F;
  Tensor z = random_tensor(Shape{n, 4, 5, 3}, 11);
  const Tensor per_video = vae.decode_frames(z, F);
  const int64_t row = per_video.numel() / n;
  ASSERT_EQ(per_video.shape(), (Shape{n, 3, 10, 6}));

  // default chunk = F: identical to the direct call; each video equals that video decoded alone
  Tensor chunked = vae.decode(z, F);
  EXPECT_EQ(max_diff(chunked.data(), per_video.data(), per_video.numel()), 0.0);
  Tensor second = vae.decode_frames(rows(z, F, F), F);
  EXPECT_LE(max_diff(second.data(), per_video.data() + F * row, second.numel()), 1e-6);

  // chunk = 4 spans both videos: rows 0..3 are one 4-frame sequence, rows 4..5 a 2-frame sequence
  Tensor c4 = vae.decode(z, F, 4);
  Tensor a = vae.decode_frames(rows(z, 0, 4), 4), b = vae.decode_frames(rows(z, 4, 2), 2);
  EXPECT_LE(max_diff(c4.data(), a.data(), a.numel()), 1e-6);
  EXPECT_LE(max_diff(c4.data() + 4 * row, b.data(), b.numel()), 1e-6);
  // ... which really differs from per-video decoding (the temporal GroupNorm and convolutions mix the videos)
  EXPECT_GT(max_diff(c4.data(), per_video.data(), per_video.numel()), 1e-3);

  // chunk = 1: every frame alone; chunk >= rows: the whole batch as one sequence
  Tensor c1 = vae.decode(z, F, 1), singles = vae.decode_frames(z, 1);
  EXPECT_LE(max_diff(c1.data(), singles.data(), singles.numel()), 1e-6);
  Tensor all = vae.decode(z, F, 100), one_seq = vae.decode_frames(z, n);
  EXPECT_LE(max_diff(all.data(), one_seq.data(), one_seq.numel()), 1e-6);
  EXPECT_GT(max_diff(c1.data(), per_video.data(), per_video.numel()), 1e-3);

  EXPECT_THROW(vae.decode(rows(z, 0, 5), F), Error);  // 5 rows are not whole videos of 3 frames
}

TEST(TemporalVae, TemporalTilesAndRecomputationDoNotChangeTheResult) {
  TemporalVAE vae(load_golden_case(golden("vae_decode")).model_dir());
  Tensor z = random_tensor(Shape{4, 4, 3, 5}, 23);
  Tensor whole = vae.decode_frames(z, 4);
  vae.set_temporal_memory({4 * 32 * 7, false});  // 7-pixel tiles (pixel counts 15/60/240 leave tails)
  Tensor tiled = vae.decode_frames(z, 4);
  EXPECT_LE(max_diff(whole.data(), tiled.data(), whole.numel()), 1e-5);
  vae.set_temporal_memory({4 * 32 * 7, true});  // the low-memory mode: no whole-clip buffer, conv1 run twice
  Tensor low = vae.decode_frames(z, 4);
  EXPECT_LE(max_diff(whole.data(), low.data(), whole.numel()), 1e-5);
}

TEST(TemporalVae, DecodeLatentsMultipliesByTheFloatReciprocal) {
  TemporalVAE vae(load_golden_case(golden("vae_decode")).model_dir());
  Tensor lat = random_tensor(Shape{2, 4, 2, 2}, 3);
  Tensor z(lat.shape());
  for (int64_t i = 0; i < z.numel(); ++i) z[i] = lat[i] * 5.489980697631836f;  // float32(1/0.18215), vae.md §5
  Tensor a = vae.decode_latents(lat, 2), b = vae.decode(z, 2);
  EXPECT_EQ(max_diff(a.data(), b.data(), a.numel()), 0.0);
}

}  // namespace
}  // namespace egopd
