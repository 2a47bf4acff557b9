// Numeric guards: a NaN in one weight, or a config value that drives the computation out of range, never ends in
// a successful run (one-line error naming the stage, no output folder); the non-finite counter against
// std::isfinite; heatmap read-out and drawing refuse NaN instead of turning it into 0 N.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <functional>
#include <fstream>
#include <limits>

#include "convert/test_util.h"
#include "core/error.h"
#include "core/finite_check.h"
#include "core/json_text.h"
#include "pipeline/predict_run.h"
#include "pipeline/synthetic_model.h"
#include "pressure/heatmap_image.h"
#include "pressure/renderer.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

TEST(FiniteCheck, CountsExactlyTheNonFiniteValues) {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const float specials[] = {0.0f, -0.0f, 1.0f, std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                            std::numeric_limits<float>::denorm_min(), inf, -inf, nan, -nan};
  for (int64_t n : {0, 1, 7, 8, 9, 31, 33, 1001}) {
    std::vector<float> v(static_cast<size_t>(n));
    for (int64_t i = 0; i < n; ++i) v[size_t(i)] = specials[(i * 7 + n) % 10];
    int64_t want = 0;
    for (float x : v) want += !std::isfinite(double(x));
    EXPECT_EQ(count_non_finite(v.data(), n), want) << n;
  }
  Tensor t({2, 3});
  for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = 1.0f;
  EXPECT_NO_THROW(require_finite(t, "x"));
  t.data()[5] = nan;
  try {
    require_finite(t, "the latents after step 2 of 4 (U-Net output)");
    FAIL() << "NaN accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "non-finite values in the latents after step 2 of 4 (U-Net output): 1 of 6; the "
                                     "model or its config is broken");
  }
}

TEST(FiniteCheck, HeatmapsRefuseNaN) {
  const HandTemplate t = HandTemplate::load(default_template_path());
  const PressureRenderer r(t, 64);
  std::vector<float> img(3 * 64 * 64, 0.0f);
  EXPECT_NO_THROW(r.heatmap_from_image(img.data()));
  img[100] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(r.heatmap_from_image(img.data()), Error);
  std::vector<double> h(64 * 64, 0.5);
  h[7] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(paint_heatmap(h, 64, r.outline_canvas(), {}), Error);
}

// A tiny model per test, broken in one place; predict must fail with one line and leave no output folder.
class Guards : public ::testing::Test {
 protected:
  fs::path root;
  void SetUp() override {
    root = fs::temp_directory_path() /
           ("egopd_guards_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root);
    write_synthetic_model((root / "model").string(), "tiny", 3, DType::F32, 4);
  }
  void TearDown() override { fs::remove_all(root); }

  std::string predict_error() {
    PredictOptions o;
    o.model_dir = (root / "model").string();
    o.frames = 2;
    o.size = 64;
    o.out_dir = (root / "out").string();
    try {
      run_predict(o);
    } catch (const Error& e) {
      EXPECT_FALSE(fs::exists(o.out_dir)) << "an output folder after a failed run";
      return e.what();
    }
    return "no error";
  }
  void edit_json(const fs::path& file, const std::function<void(nlohmann::json&)>& edit) {
    std::ifstream in(file);
    nlohmann::json j = parse_json(in);
    edit(j);
    std::ofstream(file) << dump_json(j, 2);
  }
};

TEST_F(Guards, NaNInOneUNetWeight) {
  test::set_stored_f32(root / "model" / "unet" / "diffusion_pytorch_model.safetensors", "conv_out.bias", 0,
       std::numeric_limits<float>::quiet_NaN());
  const std::string e = predict_error();
  EXPECT_NE(e.find("non-finite values in the latents after step 1 of 4 (U-Net output)"), std::string::npos) << e;
}

TEST_F(Guards, InfInTheVaeDecoder) {
  test::set_stored_f32(root / "model" / "vae" / "diffusion_pytorch_model.safetensors", "decoder.conv_out.bias", 1,
       std::numeric_limits<float>::infinity());
  const std::string e = predict_error();
  EXPECT_NE(e.find("non-finite values in the decoded heatmaps (VAE decoder output)"), std::string::npos) << e;
}

TEST_F(Guards, HugeSigmaMax) {
  edit_json(root / "model" / "scheduler" / "scheduler_config.json", [](nlohmann::json& j) { j["sigma_max"] = 1e308; });
  const std::string e = predict_error();
  EXPECT_NE(e.find("scheduler_config.json: field 'sigma_max': must be > 0 and <= 1e+06, got 1e+308"),
            std::string::npos)
      << e;
}

TEST_F(Guards, NegativeLayerNormEps) {
  edit_json(root / "model" / "text_encoder" / "config.json", [](nlohmann::json& j) { j["layer_norm_eps"] = -1e-5; });
  const std::string e = predict_error();
  EXPECT_NE(e.find("text_encoder/config.json: field 'layer_norm_eps'"), std::string::npos) << e;
}

TEST_F(Guards, HugeNoiseAugStrength) {
  edit_json(root / "model" / "model_index.json",
            [](nlohmann::json& j) { j["egopd_defaults"]["noise_aug_strength"] = 1e30; });
  const std::string e = predict_error();
  EXPECT_NE(e.find("field 'noise_aug_strength': must be >= 0 and <= 10"), std::string::npos) << e;
}

TEST_F(Guards, ZeroChannelsAndFrames) {
  edit_json(root / "model" / "vae" / "config.json", [](nlohmann::json& j) { j["latent_channels"] = 0; });
  std::string e = predict_error();
  EXPECT_NE(e.find("vae/config.json: field 'latent_channels': must be between 1 and"), std::string::npos) << e;
  fs::remove_all(root / "model");
  write_synthetic_model((root / "model").string(), "tiny", 3, DType::F32, 4);
  edit_json(root / "model" / "model_index.json", [](nlohmann::json& j) { j["egopd_defaults"]["num_frames"] = -3; });
  e = predict_error();
  EXPECT_NE(e.find("field 'num_frames': must be between 1 and 1024, got -3"), std::string::npos) << e;
}

}  // namespace
}  // namespace egopd
