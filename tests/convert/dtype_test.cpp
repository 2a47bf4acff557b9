// dtype conversion: q8 quantisation against hand-computed values, F32/F16/BF16 round trips of a whole model
// directory, and q8 directories that the runtime's models load.
#include <gtest/gtest.h>

#include <filesystem>
#include <sstream>

#include "clip_image/clip_vision.h"
#include "clip_text/clip_text.h"
#include "convert/dtype_convert.h"
#include "convert/inspect.h"
#include "core/error.h"
#include "mask_encoder/mask_encoder.h"
#include "pipeline/synthetic_model.h"
#include "test_util.h"
#include "unet3d/unet.h"
#include "vae/temporal_vae.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;
using test::ScratchDir;

// Hand-computed: row 0 max |w| = 2.54 -> scale 0.02, q = w / 0.02 rounded (50, -127, 16.65 -> 17, -5.55 -> -6);
// row 1 all zero -> scale 0, q 0; row 2 max 0.5 -> scale 0.5/127, q = w * 254 (127, 50.8 -> 51, -25.4 -> -25,
// 7.62 -> 8).
TEST(Q8, QuantisesRowsAsComputedByHand) {
  const float w[12] = {1.0f, -2.54f, 0.333f, -0.111f, 0, 0, 0, 0, 0.5f, 0.2f, -0.1f, 0.03f};
  int8_t q[12];
  float scale[3];
  quantize_rows_q8(w, 3, 4, q, scale);
  EXPECT_FLOAT_EQ(scale[0], 0.02f);
  EXPECT_EQ(scale[1], 0.0f);
  EXPECT_FLOAT_EQ(scale[2], 0.5f / 127.0f);
  const int8_t want[12] = {50, -127, 17, -6, 0, 0, 0, 0, 127, 51, -25, 8};
  for (int i = 0; i < 12; ++i) EXPECT_EQ(int(q[i]), int(want[i])) << i;
}

TEST(Q8, OnlyLinearAndConvWeightsAreQuantised) {
  EXPECT_TRUE(is_q8_quantizable("conv_in.weight", {32, 8, 3, 3}));
  EXPECT_TRUE(is_q8_quantizable("time_embedding.linear_1.weight", {128, 32}));
  EXPECT_TRUE(is_q8_quantizable("down_blocks.0.resnets.0.temporal_res_block.conv1.weight", {32, 32, 3, 1, 1}));
  EXPECT_FALSE(is_q8_quantizable("conv_in.bias", {32}));
  EXPECT_FALSE(is_q8_quantizable("norm1.weight", {32}));
  EXPECT_FALSE(is_q8_quantizable("text_model.embeddings.token_embedding.weight", {49408, 32}));
  EXPECT_FALSE(is_q8_quantizable("vision_model.embeddings.position_embedding.weight", {257, 32}));
  EXPECT_FALSE(is_q8_quantizable("time_mixer.mix_factor", {1}));
}

class DTypeDir : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("dtype");
    write_synthetic_model(dir_->str("f32"), "tiny", 11, DType::F32, 8);
  }
  static void TearDownTestSuite() { delete dir_; }
  static std::string p(const std::string& sub) { return dir_->str(sub); }
  static WeightMap load(const std::string& model, const std::string& folder) {
    return WeightMap::load_dir((fs::path(p(model)) / folder).string(), model_component(folder).stem, folder);
  }
  static inline ScratchDir* dir_ = nullptr;
};

TEST_F(DTypeDir, HalfAndBFloatRoundTrips) {
  convert_dtype(p("f32"), p("f16"), TargetDType::F16, {});
  convert_dtype(p("f16"), p("f16-f32"), TargetDType::F32, {});
  convert_dtype(p("f16-f32"), p("f16-f32-f16"), TargetDType::F16, {});
  convert_dtype(p("f32"), p("bf16"), TargetDType::BF16, {});
  convert_dtype(p("bf16"), p("bf16-f32"), TargetDType::F32, {});
  for (const auto& c : model_components()) {
    const WeightMap a = load("f32", c.folder), h = load("f16", c.folder), hf = load("f16-f32", c.folder),
                    b = load("bf16", c.folder), bf = load("bf16-f32", c.folder);
    for (const auto& k : a.keys()) {
      const Tensor v = a.find(k)->to_f32();
      ASSERT_EQ(h.find(k)->dtype, DType::F16);
      ASSERT_EQ(b.find(k)->dtype, DType::BF16);
      const auto* hv = reinterpret_cast<const uint16_t*>(h.find(k)->data);
      const auto* bv = reinterpret_cast<const uint16_t*>(b.find(k)->data);
      const Tensor hback = hf.find(k)->to_f32(), bback = bf.find(k)->to_f32();
      for (int64_t i = 0; i < v.numel(); ++i) {
        ASSERT_EQ(hv[i], float_to_half(v[i])) << k << "[" << i << "]";
        ASSERT_EQ(bv[i], float_to_bf16(v[i])) << k << "[" << i << "]";
        ASSERT_EQ(hback[i], half_to_float(float_to_half(v[i]))) << k;
        ASSERT_EQ(bback[i], bf16_to_float(float_to_bf16(v[i]))) << k;
      }
    }
    // f16 -> f32 -> f16 is lossless.
    test::expect_same_tensors(h, load("f16-f32-f16", c.folder), c.folder);
  }
  // Configs, tokenizer and scheduler are copied unchanged.
  for (const char* f : {"model_index.json", "scheduler/scheduler_config.json", "tokenizer/merges.txt", "unet/config.json"})
    EXPECT_EQ(fs::file_size(fs::path(p("f32")) / f), fs::file_size(fs::path(p("f16")) / f)) << f;
}

TEST_F(DTypeDir, Q8DirectoryStoresScalesAndLoadsInTheRuntimeModels) {
  const DTypeReport r = convert_dtype(p("f32"), p("q8"), TargetDType::Q8, {});
  EXPECT_GT(r.quantized, 0u);
  const WeightMap a = load("f32", "unet"), q = load("q8", "unet");
  const StoredTensor* w = q.find("conv_in.weight");
  ASSERT_EQ(w->dtype, DType::I8);
  const StoredTensor* s = q.find("conv_in.weight_scale");
  ASSERT_NE(s, nullptr);
  ASSERT_EQ(s->dtype, DType::F32);
  ASSERT_EQ(s->shape, std::vector<int64_t>{w->shape[0]});
  EXPECT_EQ(q.find("conv_in.bias")->dtype, DType::F32);
  // Per row: |w - q * scale| <= scale / 2.
  const Tensor orig = a.find("conv_in.weight")->to_f32(), sc = s->to_f32();
  const int64_t rows = w->shape[0], cols = orig.numel() / rows;
  for (int64_t i = 0; i < rows; ++i)
    for (int64_t j = 0; j < cols; ++j) {
      const float deq = float(int8_t(w->data[i * cols + j])) * sc[i];
      ASSERT_LE(std::fabs(deq - orig[i * cols + j]), sc[i] * 0.5f + 1e-7f);
    }
  std::ostringstream report;
  EXPECT_EQ(inspect_path(p("q8"), report, InspectOptions{false}), 0u) << report.str();

  // The runtime reads <key> I8 + <key>_scale for every quantised tensor and rejects nothing.
  const fs::path m(p("q8"));
  EXPECT_NO_THROW(UNetSpatioTemporal((m / "unet").string()));
  EXPECT_NO_THROW(TemporalVAE((m / "vae").string()));
  EXPECT_NO_THROW(ClipVisionModelWithProjection::load_dir((m / "image_encoder").string()));
  EXPECT_NO_THROW(ClipTextModel::load_dir((m / "text_encoder").string()));
  EXPECT_NO_THROW(MaskEncoder((m / "mask_encoder").string()));

  // q8 -> f32 dequantises (and drops the scales).
  convert_dtype(p("q8"), p("q8-f32"), TargetDType::F32, {});
  const WeightMap d = load("q8-f32", "unet");
  EXPECT_EQ(d.find("conv_in.weight_scale"), nullptr);
  const Tensor deq = d.find("conv_in.weight")->to_f32();
  for (int64_t i = 0; i < rows; ++i)
    for (int64_t j = 0; j < cols; ++j) ASSERT_EQ(deq[i * cols + j], float(int8_t(w->data[i * cols + j])) * sc[i]);
}

TEST_F(DTypeDir, OutputMustDifferFromInput) {
  test::expect_error([] { convert_dtype(p("f32"), p("f32"), TargetDType::F16, {}); }, {"--out", "is the input"});
}

}  // namespace
}  // namespace egopd
