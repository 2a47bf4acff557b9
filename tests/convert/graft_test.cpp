// graft: a stock (PIFR-free) tiny SVD directory grafted with a text encoder gives bit for bit the stock U-Net's
// output for any prompt and masks; and synth writes complete, loadable, deterministic model directories.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "clip_image/clip_vision.h"
#include "clip_text/clip_text.h"
#include "clip_text/clip_tokenizer.h"
#include "convert/graft.h"
#include "convert/inspect.h"
#include "convert/tensor_io.h"
#include "core/error.h"
#include "core/synthetic_weights.h"
#include "mask_encoder/mask_encoder.h"
#include "pipeline/synthetic_model.h"
#include "scheduler/sampler.h"
#include "test_util.h"
#include "unet3d/unet.h"
#include "vae/temporal_vae.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;
using test::ScratchDir;

Tensor random_tensor(const Shape& s, uint64_t seed) {
  Tensor t(s);
  synthetic_values("input", Shape{s.numel(), 1}, seed, t.data());  // U(-1, 1)
  return t;
}

// A stock SVD directory: the tiny synthetic model without PIFR, text encoder, tokenizer and mask encoder.
void write_stock_svd(const fs::path& synth, const fs::path& stock) {
  fs::create_directories(stock / "unet");
  nlohmann::json cfg = preset_config("tiny", "unet");
  cfg.erase("pifr");
  const WeightMap w = WeightMap::load_dir((synth / "unet").string(), "diffusion_pytorch_model", "unet");
  std::vector<OutTensor> keep;
  for (const auto& k : w.keys()) {
    if (k.find(".pifr.") != std::string::npos) continue;
    const StoredTensor* s = w.find(k);
    keep.push_back({k, s->dtype, s->shape, [s](uint8_t* dst) { copy_stored(*s, dst); }});
  }
  write_weights((stock / "unet").string(), "diffusion_pytorch_model", keep, {});
  write_json_atomic((stock / "unet" / "config.json").string(), cfg);
  for (const char* f : {"vae", "image_encoder", "scheduler", "feature_extractor"}) fs::copy(synth / f, stock / f);
  write_json_atomic((stock / "model_index.json").string(), {{"_class_name", "StableVideoDiffusionPipeline"}});
}

TEST(Graft, GraftedUNetWithTextEqualsTheStockUNetBitForBit) {
  ScratchDir dir("graft");
  write_synthetic_model(dir.str("synth"), "tiny", 21, DType::F32, 0);
  write_stock_svd(dir.path / "synth", dir.path / "stock");
  GraftOptions o;
  o.svd_dir = dir.str("stock");
  o.text_encoder_dir = dir.str("synth/text_encoder");
  o.tokenizer_dir = dir.str("synth/tokenizer");
  o.out_dir = dir.str("grafted");
  graft_model(o);

  std::ostringstream report;
  ASSERT_EQ(inspect_path(o.out_dir, report, InspectOptions{false}), 0u) << report.str();
  const Config cfg = Config::load(dir.str("grafted/unet/config.json"));
  EXPECT_EQ(cfg.sub("pifr").get_int("text_dim"), 32);
  EXPECT_TRUE(cfg.sub("pifr").get_bool("enabled", false));

  // The initialisation rules themselves.
  const WeightMap g = WeightMap::load_dir(dir.str("grafted/unet"), "diffusion_pytorch_model", "unet");
  const std::string b = "down_blocks.0.attentions.0.transformer_blocks.0.";
  for (const char* zero : {"pifr.mod.1.weight", "pifr.mod.1.bias"}) {
    const Tensor t = g.find(b + zero)->to_f32();
    for (int64_t i = 0; i < t.numel(); ++i) ASSERT_EQ(t[i], 0.0f) << zero;
  }
  for (const auto& [pifr, attn2] : {std::pair<const char*, const char*>{"pifr.attn_text.to_q.weight", "attn2.to_q.weight"},
                                    {"pifr.attn_text.to_out.0.weight", "attn2.to_out.0.weight"},
                                    {"pifr.attn_text.to_out.0.bias", "attn2.to_out.0.bias"}})
    EXPECT_EQ(std::memcmp(g.find(b + pifr)->data, g.find(b + attn2)->data, g.find(b + attn2)->nbytes), 0) << pifr;
  const Tensor k = g.find(b + "pifr.attn_text.to_k.weight")->to_f32();  // [32, 32]: Xavier bound sqrt(6/64)
  float kmax = 0;
  for (int64_t i = 0; i < k.numel(); ++i) kmax = std::max(kmax, std::fabs(k[i]));
  EXPECT_LE(kmax, std::sqrt(6.0f / 64.0f));
  EXPECT_GT(kmax, 0.8f * std::sqrt(6.0f / 64.0f));
  const WeightMap me = WeightMap::load_dir(dir.str("grafted/mask_encoder"), "diffusion_pytorch_model", "mask_encoder");
  for (const char* zero : {"conv_out.weight", "conv_out.bias"}) {
    const Tensor t = me.find(zero)->to_f32();
    for (int64_t i = 0; i < t.numel(); ++i) ASSERT_EQ(t[i], 0.0f) << zero;
  }

  // Same inputs through the stock U-Net (no text) and the grafted one (with a random prompt encoding).
  UNetSpatioTemporal stock(dir.str("stock/unet")), grafted(dir.str("grafted/unet"));
  const Tensor sample = random_tensor(Shape{1, 2, 8, 8, 8}, 1), ehs = random_tensor(Shape{1, 1, 32}, 2);
  const Tensor text = random_tensor(Shape{1, 77, 32}, 3);
  const Tensor ids = Tensor::from(Shape{1, 3}, {4.0f, 127.0f, 0.02f});
  const Tensor a = stock.forward(sample, 1.2f, ids, stock.prepare(ehs, nullptr));
  const Tensor c = grafted.forward(sample, 1.2f, ids, grafted.prepare(ehs, &text));
  ASSERT_EQ(a.shape(), c.shape());
  EXPECT_EQ(std::memcmp(a.data(), c.data(), size_t(a.numel()) * 4), 0) << "grafted output differs from stock";
  // And the grafted mask encoder contributes exactly zero features.
  MaskEncoder mask(dir.str("grafted/mask_encoder"));
  const Tensor mf = mask.forward(random_tensor(Shape{2, 1, 64, 64}, 4));
  for (int64_t i = 0; i < mf.numel(); ++i) ASSERT_EQ(mf[i], 0.0f);
}

TEST(Graft, RefusesAUNetThatAlreadyHasPIFR) {
  ScratchDir dir("graft-twice");
  write_synthetic_model(dir.str("m"), "tiny", 1, DType::F32, 0);
  GraftOptions o;
  o.svd_dir = dir.str("m");
  o.text_encoder_dir = dir.str("m/text_encoder");
  o.tokenizer_dir = dir.str("m/tokenizer");
  o.out_dir = dir.str("out");
  test::expect_error([&] { graft_model(o); }, {"already has PIFR"});
}

// ------------------------------------------------------------------------------------------ synth

TEST(Synth, TinyModelIsCompleteConsistentAndLoads) {
  ScratchDir dir("synth");
  const fs::path m = dir.path / "m";
  write_synthetic_model(m.string(), "tiny", 5, DType::F16, 4);
  std::ostringstream report;
  ASSERT_EQ(inspect_path(m.string(), report, InspectOptions{false}), 0u) << report.str();

  UNetSpatioTemporal unet((m / "unet").string());
  TemporalVAE vae((m / "vae").string());
  auto vision = ClipVisionModelWithProjection::load_dir((m / "image_encoder").string());
  auto text = ClipTextModel::load_dir((m / "text_encoder").string());
  MaskEncoder mask((m / "mask_encoder").string());
  auto tok = ClipTokenizer::load_dir((m / "tokenizer").string());
  auto sampler = load_sampler((m / "scheduler").string());
  EXPECT_EQ(std::string(sampler->name()), "animatelcm");

  // Dimensions the pipeline relies on.
  EXPECT_EQ(unet.config().in_channels, 8);
  EXPECT_EQ(unet.config().out_channels, 4);
  EXPECT_EQ(unet.config().cross_attention_dim[0], vision.config().projection_dim);
  EXPECT_EQ(unet.config().pifr_text_dim, text.hidden_size());
  EXPECT_EQ(vae.config().latent_channels, 4);
  EXPECT_EQ(vae.config().spatial_factor(), 8);
  EXPECT_EQ(mask.config().downscale(), 8);
  EXPECT_EQ(mask.config().conditioning_embedding_channels, 8);
  EXPECT_EQ(vision.config().image_size, 224);
  EXPECT_EQ(vision.config().patch_size, 14);
  EXPECT_EQ(text.config().max_position_embeddings, 77);
  EXPECT_EQ(text.config().vocab_size, 49408);
  const Config index = Config::load((m / "model_index.json").string());
  EXPECT_EQ(index.sub("egopd_defaults").get_int("num_inference_steps"), 4);
  EXPECT_EQ(index.get_string_list("scheduler")[1], "AnimateLCMSVDStochasticIterativeScheduler");

  // Deterministic in the seed: same seed, same bytes; another seed, other values.
  write_synthetic_model(dir.str("again"), "tiny", 5, DType::F16, 4);
  write_synthetic_model(dir.str("other"), "tiny", 6, DType::F16, 4);
  for (const auto& c : model_components()) {
    const std::string f = std::string(c.folder) + "/" + c.stem + ".safetensors";
    std::ifstream x(m / f, std::ios::binary), y(dir.path / "again" / f, std::ios::binary), z(dir.path / "other" / f, std::ios::binary);
    const std::string bx((std::istreambuf_iterator<char>(x)), {}), by((std::istreambuf_iterator<char>(y)), {}),
        bz((std::istreambuf_iterator<char>(z)), {});
    EXPECT_EQ(bx, by) << f;
    EXPECT_NE(bx, bz) << f;
  }
}

TEST(Synth, EulerByDefaultAndBadStepCountsRejected) {
  ScratchDir dir("synth-euler");
  write_synthetic_model(dir.str("m"), "tiny", 1, DType::BF16, 0);
  EXPECT_EQ(std::string(load_sampler(dir.str("m/scheduler"))->name()), "euler");
  EXPECT_EQ(Config::load(dir.str("m/model_index.json")).sub("egopd_defaults").get_int("num_inference_steps"), 25);
  test::expect_error([&] { write_synthetic_model(dir.str("bad"), "tiny", 1, DType::F32, 41); }, {"--lcm-steps", "41"});
  test::expect_error([&] { write_synthetic_model(dir.str("bad"), "small", 1, DType::F32, 0); }, {"preset", "small"});
}

}  // namespace
}  // namespace egopd
