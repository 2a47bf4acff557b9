// from-original: spec examples of the key mapping, the real-size key sets (no data needed), and a tiny model
// exported to the original single-file naming by an independent inverse and converted back, tensor for tensor.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "convert/from_original.h"
#include "convert/inspect.h"
#include "convert/original_mapping.h"
#include "core/error.h"
#include "core/safetensors.h"
#include "original_export.h"
#include "pipeline/synthetic_model.h"
#include "test_util.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;
using test::ScratchDir;

OriginalLayout svd_layout() {
  OriginalLayout l;
  l.unet = UNetConfig::svd_xt(false);
  return l;
}

// weights.md §4.5, verbatim.
TEST(OriginalMapping, SpecExamples) {
  const struct {
    const char* original;
    const char* component;
    const char* key;
  } rows[] = {
      {"model.diffusion_model.input_blocks.0.0.weight", "unet", "conv_in.weight"},
      {"model.diffusion_model.time_embed.2.bias", "unet", "time_embedding.linear_2.bias"},
      {"model.diffusion_model.label_emb.0.0.weight", "unet", "add_embedding.linear_1.weight"},
      {"model.diffusion_model.input_blocks.4.0.skip_connection.weight", "unet",
       "down_blocks.1.resnets.0.spatial_res_block.conv_shortcut.weight"},
      {"model.diffusion_model.input_blocks.5.0.time_stack.emb_layers.1.weight", "unet",
       "down_blocks.1.resnets.1.temporal_res_block.time_emb_proj.weight"},
      {"model.diffusion_model.input_blocks.5.0.time_mixer.mix_factor", "unet", "down_blocks.1.resnets.1.time_mixer.mix_factor"},
      {"model.diffusion_model.input_blocks.6.0.op.weight", "unet", "down_blocks.1.downsamplers.0.conv.weight"},
      {"model.diffusion_model.input_blocks.7.1.time_stack.0.ff_in.net.0.proj.weight", "unet",
       "down_blocks.2.attentions.0.temporal_transformer_blocks.0.ff_in.net.0.proj.weight"},
      {"model.diffusion_model.input_blocks.8.1.time_pos_embed.2.bias", "unet",
       "down_blocks.2.attentions.1.time_pos_embed.linear_2.bias"},
      {"model.diffusion_model.input_blocks.10.0.in_layers.2.weight", "unet", "down_blocks.3.resnets.0.spatial_res_block.conv1.weight"},
      {"model.diffusion_model.middle_block.1.transformer_blocks.0.attn2.to_k.weight", "unet",
       "mid_block.attentions.0.transformer_blocks.0.attn2.to_k.weight"},
      {"model.diffusion_model.middle_block.2.time_stack.out_layers.3.bias", "unet", "mid_block.resnets.1.temporal_res_block.conv2.bias"},
      {"model.diffusion_model.output_blocks.2.1.conv.weight", "unet", "up_blocks.0.upsamplers.0.conv.weight"},
      {"model.diffusion_model.output_blocks.4.1.proj_in.weight", "unet", "up_blocks.1.attentions.1.proj_in.weight"},
      {"model.diffusion_model.output_blocks.8.2.conv.bias", "unet", "up_blocks.2.upsamplers.0.conv.bias"},
      {"model.diffusion_model.output_blocks.11.0.out_layers.0.weight", "unet", "up_blocks.3.resnets.2.spatial_res_block.norm2.weight"},
      {"model.diffusion_model.out.2.weight", "unet", "conv_out.weight"},
      {"conditioner.embedders.3.encoder.encoder.down.1.block.0.nin_shortcut.weight", "vae",
       "encoder.down_blocks.1.resnets.0.conv_shortcut.weight"},
      {"conditioner.embedders.3.encoder.encoder.mid.attn_1.q.weight", "vae", "encoder.mid_block.attentions.0.to_q.weight"},
      {"conditioner.embedders.3.encoder.quant_conv.weight", "vae", "quant_conv.weight"},
      {"first_stage_model.decoder.up.3.block.0.conv1.weight", "vae", "decoder.up_blocks.0.resnets.0.spatial_res_block.conv1.weight"},
      {"first_stage_model.decoder.up.1.block.0.time_stack.in_layers.2.weight", "vae",
       "decoder.up_blocks.2.resnets.0.temporal_res_block.conv1.weight"},
      {"first_stage_model.decoder.up.0.block.2.mix_factor", "vae", "decoder.up_blocks.3.resnets.2.time_mixer.mix_factor"},
      {"first_stage_model.decoder.up.2.upsample.conv.weight", "vae", "decoder.up_blocks.1.upsamplers.0.conv.weight"},
      {"first_stage_model.decoder.conv_out.time_mix_conv.weight", "vae", "decoder.time_conv_out.weight"},
      {"conditioner.embedders.0.open_clip.model.visual.proj", "image_encoder", "visual_projection.weight"},
  };
  for (const auto& r : rows) {
    const KeyMapping m = map_original_key(r.original, svd_layout());
    ASSERT_EQ(m.kind, KeyMapping::Mapped) << r.original;
    ASSERT_EQ(m.targets.size(), 1u) << r.original;
    EXPECT_EQ(m.targets[0].component, r.component) << r.original;
    EXPECT_EQ(m.targets[0].key, r.key) << r.original;
  }
  const KeyMapping q = map_original_key("conditioner.embedders.3.encoder.encoder.mid.attn_1.q.weight", svd_layout());
  EXPECT_EQ(q.targets[0].transform, KeyTransform::Squeeze);
  EXPECT_EQ(transformed_shape("q", {512, 512, 1, 1}, KeyTransform::Squeeze), (std::vector<int64_t>{512, 512}));
  const KeyMapping p = map_original_key("conditioner.embedders.0.open_clip.model.visual.proj", svd_layout());
  EXPECT_EQ(p.targets[0].transform, KeyTransform::Transpose);
  EXPECT_EQ(transformed_shape("proj", {1280, 1024}, KeyTransform::Transpose), (std::vector<int64_t>{1024, 1280}));

  const KeyMapping f = map_original_key(
      "conditioner.embedders.0.open_clip.model.visual.transformer.resblocks.31.attn.in_proj_weight", svd_layout());
  ASSERT_EQ(f.targets.size(), 3u);
  const char* qkv[] = {"q", "k", "v"};
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(f.targets[size_t(i)].key, std::string("vision_model.encoder.layers.31.self_attn.") + qkv[i] + "_proj.weight");
    EXPECT_EQ(transformed_shape("w", {3840, 1280}, f.targets[size_t(i)].transform), (std::vector<int64_t>{1280, 1280}));
  }
}

TEST(OriginalMapping, DroppedAndUnknownKeys) {
  const OriginalLayout l = svd_layout();
  for (const char* k : {"model_ema.decay", "conditioner.embedders.0.open_clip.model.logit_scale",
                        "conditioner.embedders.0.open_clip.model.token_embedding.weight",
                        "conditioner.embedders.0.open_clip.model.ln_final.weight",
                        "conditioner.embedders.0.open_clip.model.positional_embedding",
                        "first_stage_model.encoder.conv_in.weight", "conditioner.embedders.3.encoder.decoder.conv_in.weight",
                        "conditioner.embedders.3.encoder.post_quant_conv.bias"})
    EXPECT_EQ(map_original_key(k, l).kind, KeyMapping::Dropped) << k;
  for (const char* k : {"foo.bar", "model.diffusion_model.input_blocks.99.0.in_layers.0.weight",
                        "model.diffusion_model.input_blocks.1.0.bogus.weight", "model.diffusion_model.input_blocks.10.1.norm.weight",
                        "first_stage_model.decoder.up.7.block.0.conv1.weight", "conditioner.embedders.0.open_clip.model.visual.bogus"})
    EXPECT_EQ(map_original_key(k, l).kind, KeyMapping::Unknown) << k;
  OriginalLayout no_cond = l;
  no_cond.has_conditioning_encoder = false;
  const KeyMapping m = map_original_key("first_stage_model.encoder.norm_out.weight", no_cond);
  ASSERT_EQ(m.kind, KeyMapping::Mapped);
  EXPECT_EQ(m.targets[0].key, "encoder.conv_norm_out.weight");
}

// Every real-size SVD-xt parameter, sent through the test's inverse and back through the converter's rules:
// exactly the 1428 / 374 / 520 tensors with their shapes, without any data.
TEST(OriginalMapping, RealSizeKeySetsRoundTrip) {
  test::ExportLayout el;  // SVD-xt structure
  nlohmann::json unet = preset_config("svd-xt", "unet");
  unet.erase("pifr");
  const std::map<std::string, size_t> counts = {{"unet", 1428}, {"vae", 374}, {"image_encoder", 520}};
  std::map<std::string, std::vector<int64_t>> original;  // original key -> shape
  std::map<std::string, std::map<std::string, std::vector<int64_t>>> expected;
  for (const auto& [folder, count] : counts) {
    const nlohmann::json cfg = folder == "unet" ? unet : preset_config("svd-xt", folder);
    const auto params = component_parameters(folder, Config(cfg, folder));
    EXPECT_EQ(params.size(), count) << folder;
    for (const auto& [key, shape] : params) {
      expected[folder][key] = shape.vec();
      const test::OriginalPiece p = folder == "unet"  ? test::unet_to_original(key, shape.vec(), el)
                                    : folder == "vae" ? test::vae_to_original(key, shape.vec(), el, true)
                                                      : test::vision_to_original(key, shape.vec());
      original[p.key] = p.shape;
    }
  }
  std::map<std::string, std::map<std::string, std::vector<int64_t>>> got;
  for (const auto& [key, shape] : original) {
    const KeyMapping m = map_original_key(key, svd_layout());
    ASSERT_EQ(m.kind, KeyMapping::Mapped) << key;
    for (const auto& t : m.targets) {
      EXPECT_FALSE(got[t.component].count(t.key)) << t.key << " mapped twice";
      got[t.component][t.key] = transformed_shape(key, shape, t.transform);
    }
  }
  for (const auto& [folder, count] : counts) EXPECT_EQ(got[folder], expected[folder]) << folder;
}

// ------------------------------------------------------------------------------------------ tiny round trip

using OriginalTensors = std::map<std::string, Tensor>;

class FromOriginalTiny : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("from-original");
    write_synthetic_model(dir_->str("model"), "tiny", 7, DType::F32, 0);
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string model(const std::string& sub) { return (dir_->path / "model" / sub).string(); }

  // The tiny model's unet / vae / image_encoder in the original naming (plus tensors the converter must drop).
  static OriginalTensors export_original(bool with_cond_encoder) {
    const nlohmann::json ucfg = preset_config("tiny", "unet");
    test::ExportLayout el;
    el.unet_layers = ucfg["layers_per_block"].get<int64_t>();
    el.up_attention.clear();
    for (const auto& t : ucfg["up_block_types"]) el.up_attention.push_back(t.get<std::string>().rfind("CrossAttn", 0) == 0);
    el.vae_levels = int64_t(preset_config("tiny", "vae")["block_out_channels"].size());
    OriginalTensors out;
    for (const char* folder : {"unet", "vae", "image_encoder"}) {
      const WeightMap w = WeightMap::load_dir(model(folder), model_component(folder).stem, folder);
      for (const auto& key : w.keys()) {
        const StoredTensor* s = w.find(key);
        const std::string f = folder;
        if (f == "vae" && !with_cond_encoder && key.rfind("quant_conv.", 0) == 0) continue;
        const test::OriginalPiece p = f == "unet"  ? test::unet_to_original(key, s->shape, el)
                                      : f == "vae" ? test::vae_to_original(key, s->shape, el, with_cond_encoder)
                                                   : test::vision_to_original(key, s->shape);
        const Tensor v = s->to_f32();
        auto it = out.find(p.key);
        if (it == out.end()) it = out.emplace(p.key, Tensor::zeros(Shape(p.shape))).first;
        float* dst = it->second.data();
        if (p.how == test::OriginalPiece::Transposed) {
          const int64_t rows = s->shape[0], cols = s->shape[1];
          for (int64_t i = 0; i < rows; ++i)
            for (int64_t j = 0; j < cols; ++j) dst[j * rows + i] = v[i * cols + j];
        } else {
          std::memcpy(dst + p.part * v.numel(), v.data(), size_t(v.numel()) * 4);
        }
        // The first-stage engine's own encoder is an unused duplicate of the conditioning encoder.
        if (f == "vae" && with_cond_encoder && key.rfind("encoder.", 0) == 0)
          out.emplace("first_stage_model." + key, v.clone().reshaped(Shape(s->shape)));
      }
    }
    out.emplace("conditioner.embedders.0.open_clip.model.logit_scale", Tensor::full(Shape{1}, 4.6f));
    out.emplace("conditioner.embedders.0.open_clip.model.ln_final.weight", Tensor::full(Shape{32}, 1.0f));
    return out;
  }

  static std::string write_original(const OriginalTensors& t, const std::string& name) {
    std::vector<TensorToWrite> w;
    for (const auto& [k, v] : t) w.push_back(to_write(k, v));
    const std::string path = dir_->str(name);
    write_safetensors(path, w, {{"format", "pt"}});
    return path;
  }

  static inline ScratchDir* dir_ = nullptr;
};

TEST_F(FromOriginalTiny, RoundTripIsTensorForTensorIdentical) {
  const OriginalTensors original = export_original(true);
  size_t duplicates = 0;
  for (const auto& [k, v] : original) duplicates += k.rfind("first_stage_model.encoder.", 0) == 0;
  ASSERT_GT(duplicates, 0u);
  const std::string src = write_original(original, "original.safetensors");
  const std::string out = dir_->str("converted");
  FromOriginalOptions o;
  o.preset = "tiny";
  const FromOriginalReport r = convert_from_original(src, out, o);
  EXPECT_EQ(r.dropped, duplicates + 2);  // the first-stage encoder copy and the two text-tower leftovers
  EXPECT_EQ(r.mapped + r.dropped, original.size());
  for (const char* folder : {"unet", "vae", "image_encoder"}) {
    const std::string stem = model_component(folder).stem;
    test::expect_same_tensors(WeightMap::load_dir(model(folder), stem, folder),
                              WeightMap::load_dir((fs::path(out) / folder).string(), stem, folder), folder);
  }
  const Config unet = Config::load((fs::path(out) / "unet" / "config.json").string());
  EXPECT_EQ(unet.sub("pifr").get_int("text_dim"), 32);  // PIFR layers in the original naming keep their suffix
  std::ostringstream report;
  EXPECT_EQ(inspect_path(out, report, InspectOptions{false}), 0u) << report.str();
}

TEST_F(FromOriginalTiny, WithoutConditioningEncoderUsesFirstStageEncoderAndIdentityQuantConv) {
  const std::string src = write_original(export_original(false), "original-noenc.safetensors");
  const std::string out = dir_->str("converted-noenc");
  FromOriginalOptions o;
  o.preset = "tiny";
  convert_from_original(src, out, o);
  const WeightMap a = WeightMap::load_dir(model("vae"), "diffusion_pytorch_model", "vae");
  const WeightMap b = WeightMap::load_dir((fs::path(out) / "vae").string(), "diffusion_pytorch_model", "vae");
  ASSERT_EQ(a.keys(), b.keys());
  for (const auto& k : a.keys()) {
    if (k.rfind("quant_conv.", 0) == 0) continue;
    EXPECT_EQ(std::memcmp(a.find(k)->data, b.find(k)->data, a.find(k)->nbytes), 0) << k;
  }
  const Tensor w = b.find("quant_conv.weight")->to_f32();
  ASSERT_EQ(b.find("quant_conv.weight")->shape, (std::vector<int64_t>{8, 8, 1, 1}));
  for (int64_t i = 0; i < 8; ++i)
    for (int64_t j = 0; j < 8; ++j) EXPECT_EQ(w[i * 8 + j], i == j ? 1.0f : 0.0f);
  const Tensor bias = b.find("quant_conv.bias")->to_f32();
  for (int64_t i = 0; i < 8; ++i) EXPECT_EQ(bias[i], 0.0f);
}

TEST_F(FromOriginalTiny, UnmappedMissingAndMisshapedKeysAreOneErrorNamingThem) {
  const std::string out = dir_->str("converted-bad");
  FromOriginalOptions o;
  o.preset = "tiny";
  {
    OriginalTensors t = export_original(true);
    t.emplace("model.diffusion_model.input_blocks.1.0.extra_layer.weight", Tensor::zeros(Shape{2}));
    const std::string src = write_original(t, "bad-extra.safetensors");
    test::expect_error([&] { convert_from_original(src, out, o); },
                       {"not mapped", "model.diffusion_model.input_blocks.1.0.extra_layer.weight"});
  }
  {
    OriginalTensors t = export_original(true);
    t.erase("model.diffusion_model.out.2.bias");
    const std::string src = write_original(t, "bad-missing.safetensors");
    test::expect_error([&] { convert_from_original(src, out, o); }, {"unet", "missing", "conv_out.bias [4]"});
  }
  {
    OriginalTensors t = export_original(true);
    t.erase("first_stage_model.decoder.conv_in.bias");
    t.emplace("first_stage_model.decoder.conv_in.bias", Tensor::zeros(Shape{31}));
    const std::string src = write_original(t, "bad-shape.safetensors");
    test::expect_error([&] { convert_from_original(src, out, o); },
                       {"vae", "decoder.conv_in.bias has [31], expected [32]"});
  }
  EXPECT_FALSE(fs::exists(fs::path(out) / "model_index.json")) << "nothing is written on error";
}

}  // namespace
}  // namespace egopd
