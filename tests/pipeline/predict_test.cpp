// End to end on a tiny synthetic model at 64 x 64: `predict` writes every output, taxels.csv has F rows of 162
// non-negative values; `counterfactual` reuses one encoding (a variant equals the plain prediction with the same
// prompt and seed) and writes one folder per variant plus the comparison and the force table.
#include <gtest/gtest.h>
#include <unistd.h>

#include <csignal>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/interrupt.h"
#include "core/json_text.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/predict_run.h"
#include "pipeline/synthetic_model.h"
#include "pressure/taxel_csv.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

// One model and clip for the whole suite (writing the model is the slow part of the setup).
class Predict : public ::testing::Test {
 protected:
  static fs::path root;
  static void SetUpTestSuite() {
    root = fs::temp_directory_path() / ("egopd_predict_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root / "frames");
    fs::create_directories(root / "masks");
    write_synthetic_model((root / "model").string(), "tiny", 7, DType::F32, 0);
    const auto clip = synthetic_sample_clip(5, 96);
    for (size_t i = 0; i < clip.size(); ++i) {
      cv::Mat bgr;
      cv::cvtColor(clip[i], bgr, cv::COLOR_RGB2BGR);
      char name[32];
      std::snprintf(name, sizeof name, "f%zu.png", i);
      cv::imwrite((root / "frames" / name).string(), bgr);
    }
    for (int i = 0; i < 2; ++i) {
      cv::Mat m(96, 96, CV_8UC1, cv::Scalar(0));
      cv::circle(m, cv::Point(48 + 8 * i, 60), 25, cv::Scalar(255), cv::FILLED);
      cv::imwrite((root / "masks" / (i ? "m1.png" : "m0.png")).string(), m);
    }
    std::ofstream(root / "meta.json") << R"({"obj_name": "a CocaCola", "weight": 355, "material": "aluminum"})";
  }
  static void TearDownTestSuite() { fs::remove_all(root); }

  static PredictOptions options(const std::string& out) {
    PredictOptions o;
    o.model_dir = (root / "model").string();
    o.video = (root / "frames").string();
    o.frames = 2;
    o.size = 64;
    o.steps = 2;
    o.seed = 3;
    o.out_dir = (root / out).string();
    return o;
  }
  static std::string read(const fs::path& p) {
    std::ifstream in(p);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }
};
fs::path Predict::root;

void expect_prediction_folder(const fs::path& dir, int64_t frames) {
  for (int64_t f = 0; f < frames; ++f) {
    char name[48];  // room for any long long
    std::snprintf(name, sizeof name, "heatmap_%03lld.png", static_cast<long long>(f));
    const cv::Mat png = cv::imread((dir / name).string());
    ASSERT_FALSE(png.empty()) << dir / name;
    EXPECT_EQ(png.rows, 64);
  }
  EXPECT_GT(fs::file_size(dir / "side_by_side.mp4"), 0u);
  const TaxelSequence t = read_taxel_csv((dir / "taxels.csv").string());  // rejects negative values
  EXPECT_EQ(t.num_frames(), frames);
  EXPECT_EQ(t.num_taxels, 162);
  for (double v : t.values) EXPECT_GE(v, 0.0);
  for (const auto& e : fs::directory_iterator(dir))  // no temporary files left behind
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
}

TEST_F(Predict, WritesEveryOutput) {
  PredictOptions o = options("plain");
  o.meta_path = (root / "meta.json").string();
  o.masks_dir = (root / "masks").string();
  ASSERT_EQ(run_predict(o), 0);
  const fs::path out = root / "plain";
  expect_prediction_folder(out, 2);
  const auto j = parse_json(read(out / "summary.json"));
  EXPECT_EQ(j["prompt"].get<std::string>(), "This video shows the action of picking up a CocaCola. The weight of a CocaCola is 355g, "
                         "and its surface material is aluminum.");
  EXPECT_EQ(j["seed"].get<int>(), 3);
  EXPECT_EQ(j["sampler"].get<std::string>(), "euler");
  EXPECT_EQ(j["steps"].get<int>(), 2);
  EXPECT_EQ(j["frames"].get<int>(), 2);
  EXPECT_EQ(j["size"].get<int>(), 64);
  EXPECT_EQ(j["per_frame"].size(), 2u);
  EXPECT_EQ(j["per_frame"][1]["source_index"].get<int>(), 4);
  EXPECT_TRUE(j["template"]["synthetic"].get<bool>());
  EXPECT_GT(j["timings_s"]["denoise"].get<double>(), 0.0);
  EXPECT_GT(j["timings_s"]["total"].get<double>(), 0.0);
  EXPECT_GT(j["peak_rss_bytes"].get<double>(), 0.0);
}

TEST_F(Predict, CounterfactualReusesEncodingAndMatchesPredict) {
  PredictOptions o = options("cf");
  o.meta_path = (root / "meta.json").string();
  ASSERT_EQ(run_counterfactual(o, parse_vary("weight=1000,omit")), 0);
  const fs::path out = root / "cf";
  expect_prediction_folder(out / "weight_1000g", 2);
  expect_prediction_folder(out / "weight_omit", 2);
  EXPECT_FALSE(cv::imread((out / "comparison.png").string()).empty());
  const std::string csv = read(out / "forces.csv");
  EXPECT_NE(csv.find("\nweight_1000g,weight,\"1000g\","), std::string::npos) << csv;
  EXPECT_NE(csv.find("\nweight_omit,weight,\"omit\","), std::string::npos) << csv;
  const auto j = parse_json(read(out / "weight_omit" / "summary.json"));
  EXPECT_EQ(j["prompt"].get<std::string>(), "This video shows the action of picking up a CocaCola. The surface material of a CocaCola "
                         "is aluminum.");

  // The same prompt and seed through predict gives the same taxels: the shared conditioning and noise are exact.
  PredictOptions p = options("single");
  std::ofstream(root / "meta1000.json") << R"({"obj_name": "a CocaCola", "weight": 1000, "material": "aluminum"})";
  p.meta_path = (root / "meta1000.json").string();
  ASSERT_EQ(run_predict(p), 0);
  EXPECT_EQ(read(root / "single" / "taxels.csv"), read(out / "weight_1000g" / "taxels.csv"));
}

TEST_F(Predict, OneLineErrors) {
  PredictOptions o = options("err");
  o.masks_dir = (root / "masks").string();
  o.frames = 3;  // 2 masks
  EXPECT_THROW(run_predict(o), Error);
  o = options("err");
  o.size = 96;
  EXPECT_THROW(run_predict(o), Error);
  o = options("err");
  o.video = (root / "missing.mp4").string();
  EXPECT_THROW(run_predict(o), Error);
  o = options("err");
  o.model_dir = (root / "frames").string();  // not a model directory
  EXPECT_THROW(run_predict(o), Error);
  o = options("err");
  o.prompt = "a prompt";
  o.meta_path = (root / "meta.json").string();
  EXPECT_THROW(run_predict(o), Error);
  o.meta_path.clear();
  EXPECT_THROW(run_counterfactual(o, parse_vary("weight=1")), Error);  // a verbatim prompt cannot be varied
}

// Names in a folder that belong to a temporary output (AtomicDir's `.<name>.tmp-*` or a writer's `*.tmp.*`).
int temporaries_in(const fs::path& dir) {
  int n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp") != std::string::npos) ++n;
  return n;
}

TEST_F(Predict, RerunReplacesTheFolderAsAWhole) {
  PredictOptions o = options("rerun");
  o.frames = 3;
  ASSERT_EQ(run_predict(o), 0);
  ASSERT_TRUE(fs::exists(root / "rerun" / "heatmap_002.png"));
  o.frames = 2;
  ASSERT_EQ(run_predict(o), 0);
  expect_prediction_folder(root / "rerun", 2);
  EXPECT_FALSE(fs::exists(root / "rerun" / "heatmap_002.png"));  // nothing of the earlier, longer run survives
  EXPECT_EQ(temporaries_in(root), 0);
}

TEST_F(Predict, FailedOrInterruptedRunKeepsThePreviousFolder) {
  PredictOptions o = options("keep");
  ASSERT_EQ(run_predict(o), 0);
  const std::string before = read(root / "keep" / "taxels.csv");

  PredictOptions bad = o;
  bad.masks_dir = (root / "masks").string();
  bad.frames = 3;  // 2 masks: fails after the model loaded
  EXPECT_THROW(run_predict(bad), Error);
  EXPECT_EQ(read(root / "keep" / "taxels.csv"), before);
  EXPECT_EQ(temporaries_in(root), 0);

  PredictOptions other = o;
  other.seed = 4;
  request_interrupt(SIGTERM);  // as if SIGTERM arrived during the run: it stops at the first safe point
  try {
    run_predict(other);
    ADD_FAILURE() << "no Interrupted";
  } catch (const Interrupted& e) {
    EXPECT_EQ(e.exit_code(), 143);
  }
  clear_interrupt();
  EXPECT_EQ(read(root / "keep" / "taxels.csv"), before);
  EXPECT_EQ(temporaries_in(root), 0);

  PredictOptions cf = options("keep_cf");
  request_interrupt(SIGINT);
  EXPECT_THROW(run_counterfactual(cf, parse_vary("weight=1,omit")), Interrupted);
  clear_interrupt();
  EXPECT_FALSE(fs::exists(cf.out_dir));
  EXPECT_EQ(temporaries_in(root), 0);

  // A folder that is not an earlier output of the command (here: predict's, for counterfactual) is never replaced.
  try {
    run_counterfactual(o, parse_vary("weight=1,omit"));
    ADD_FAILURE() << "replaced a folder that is not a counterfactual output";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is not an earlier output of this command (no forces.csv)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(read(root / "keep" / "taxels.csv"), before);
}

}  // namespace
}  // namespace egopd
