// The C API (include/egopd.h) on a tiny synthetic model at 64 x 64. Expected taxels come from the `egopd` command's
// taxels.csv for the same inputs and seed (run as a separate process), compared byte for byte after formatting
// the API's doubles the way the CSV is written (shortest round trip). Also: frames and masks from memory, the
// output folder, counterfactuals, bad input (one-line errors, never a crash), cancelling from the progress callback
// (the model stays usable), two threads on one model, 50 predictions on one model without growing, and the block
// cache given back with the last model.
#include <gtest/gtest.h>
#include <unistd.h>

#include <charconv>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/block_pool.h"
#include "core/memory.h"
#include "egopd.h"
#include "memory_growth.h"
#include "pipeline/media.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

fs::path root;

std::string read(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// The suite's clip files: root/frames/f<i>.png and root/masks/m<i>.png.
fs::path numbered_png(const std::string& folder, size_t i) {
  return root / folder / (folder.substr(0, 1) + std::to_string(i) + ".png");
}

// taxels.csv's layout: header frame,p0..p{M-1}; one row per frame; shortest round-trip decimals.
std::string taxels_csv(const egopd_result* r) {
  const int64_t F = egopd_result_frames(r), M = egopd_result_num_taxels(r);
  std::string out = "frame";
  for (int64_t m = 0; m < M; ++m) out += ",p" + std::to_string(m);
  out += '\n';
  char buf[64];
  for (int64_t f = 0; f < F; ++f) {
    out += std::to_string(f);
    for (int64_t m = 0; m < M; ++m) {
      const auto c = std::to_chars(buf, buf + sizeof buf, egopd_result_taxels(r)[f * M + m]);
      out += ',';
      out.append(buf, c.ptr);
    }
    out += '\n';
  }
  return out;
}

// Runs the egopd command; returns its exit status.
int cli(const std::string& args) {
  const std::string cmd = std::string(EGOPD_CLI) + " " + args + " >>" + (root / "cli.log").string() + " 2>&1";
  const int st = std::system(cmd.c_str());
  return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

const std::string kCommon = " --frames 2 --size 64 --steps 2 --threads 2";

// The CLI's taxels.csv for `args` (run once per distinct args).
std::string cli_taxels(const std::string& args) {
  static std::map<std::string, std::string> cache;
  if (cache.count(args)) return cache[args];
  const fs::path out = root / ("cli_" + std::to_string(cache.size()));
  EXPECT_EQ(cli("predict --model " + (root / "model").string() + kCommon + " " + args + " --out " + out.string()), 0)
      << read(root / "cli.log");
  return cache[args] = read(out / "taxels.csv");
}

class Api : public ::testing::Test {
 protected:
  static egopd_model* model;
  static std::vector<uint8_t> frames, masks;
  static int H, W;

  static void SetUpTestSuite() {
    root = fs::temp_directory_path() / ("egopd_api_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root / "frames");
    fs::create_directories(root / "masks");
    write_synthetic_model((root / "model").string(), "tiny", 7, DType::F32, 0);
    const auto clip = synthetic_sample_clip(5, 96);
    H = 96, W = 96;
    for (size_t i = 0; i < clip.size(); ++i) {
      cv::Mat bgr;
      cv::cvtColor(clip[i], bgr, cv::COLOR_RGB2BGR);
      cv::imwrite(numbered_png("frames", i).string(), bgr);
    }
    for (int i = 0; i < 2; ++i) {
      cv::Mat m(96, 96, CV_8UC1, cv::Scalar(0));
      cv::circle(m, cv::Point(48 + 8 * i, 60), 25, cv::Scalar(255), cv::FILLED);
      cv::imwrite(numbered_png("masks", size_t(i)).string(), m);
    }
    // The in-memory copies are what a caller decodes from those files (RGB / grey).
    for (size_t i = 0; i < clip.size(); ++i) {
      cv::Mat rgb;
      cv::cvtColor(cv::imread(numbered_png("frames", i).string()), rgb, cv::COLOR_BGR2RGB);
      frames.insert(frames.end(), rgb.data, rgb.data + rgb.total() * 3);
    }
    for (int i = 0; i < 2; ++i) {
      const cv::Mat g = cv::imread(numbered_png("masks", size_t(i)).string(), cv::IMREAD_GRAYSCALE);
      masks.insert(masks.end(), g.data, g.data + g.total());
    }
    std::ofstream(root / "meta.json") << R"({"obj_name": "a CocaCola", "weight": 355, "material": "aluminum"})";
    egopd_load_options lo;
    egopd_load_options_init(&lo);
    lo.size = 64;
    lo.threads = 2;
    ASSERT_EQ(egopd_model_load((root / "model").c_str(), &lo, &model), EGOPD_OK) << egopd_last_error();
  }
  static void TearDownTestSuite() {
    egopd_model_free(model);
    model = nullptr;
    fs::remove_all(root);
  }

  static egopd_predict_options options() {
    egopd_predict_options o;
    egopd_predict_options_init(&o);
    o.num_frames = 2;
    o.steps = 2;
    return o;
  }
  static void use_memory_frames(egopd_predict_options& o) {
    o.frames = frames.data();
    o.frames_bytes = frames.size();
    o.frames_count = 5, o.frames_height = H, o.frames_width = W;
  }
  static std::string predict_csv(const egopd_predict_options& o, egopd_model* m = model) {
    egopd_result* r = nullptr;
    const egopd_status st = egopd_predict(m, &o, &r);
    EXPECT_EQ(st, EGOPD_OK) << egopd_last_error();
    if (st != EGOPD_OK) return "";
    const std::string csv = taxels_csv(r);
    egopd_result_free(r);
    return csv;
  }
  // A model of a test's own: the shared one's load options (size 64, 2 threads) changed by `adjust`.
  template <class Adjust>
  static egopd_model* own_model(Adjust adjust) {
    egopd_load_options lo;
    egopd_load_options_init(&lo);
    lo.size = 64;
    lo.threads = 2;
    adjust(lo);
    egopd_model* m = nullptr;
    EXPECT_EQ(egopd_model_load((root / "model").c_str(), &lo, &m), EGOPD_OK) << egopd_last_error();
    return m;
  }
  // The taxels of the frame-folder clip (seed 3) on a model of its own with `precision` and `conv`.
  static std::string own_model_csv(const char* precision, const char* conv) {
    egopd_model* const m = own_model([&](egopd_load_options& lo) { lo.precision = precision, lo.conv = conv; });
    if (!m) return "";
    const std::string video = (root / "frames").string();
    egopd_predict_options o = options();
    o.video = video.c_str();
    o.seed = 3;
    const std::string csv = predict_csv(o, m);
    egopd_model_free(m);
    return csv;
  }
};
egopd_model* Api::model = nullptr;
std::vector<uint8_t> Api::frames, Api::masks;
int Api::H = 0, Api::W = 0;

TEST_F(Api, FrameFolderMatchesTheCommand) {
  egopd_predict_options o = options();
  const std::string video = (root / "frames").string();
  o.video = video.c_str();
  o.seed = 3;
  const std::string want = cli_taxels("--video " + video + " --seed 3");
  ASSERT_FALSE(want.empty());
  EXPECT_EQ(predict_csv(o), want);
}

// A model loaded with precision "int8" (or "bf16") computes in it, as `egopd predict --precision` does, and a model
// loaded in fp32 afterwards is back in fp32 (the precision is the model's, set for each of its calls).
TEST_F(Api, PrecisionIsTheModels) {
  const std::string video = (root / "frames").string();
  egopd_predict_options o = options();
  o.video = video.c_str();
  o.seed = 3;
  for (const char* precision : {"int8", "bf16"}) {
    const std::string got = own_model_csv(precision, nullptr);
    EXPECT_EQ(got, cli_taxels("--video " + video + " --seed 3 --precision " + precision)) << precision;
    EXPECT_NE(got, cli_taxels("--video " + video + " --seed 3")) << precision;
    EXPECT_EQ(predict_csv(o), cli_taxels("--video " + video + " --seed 3")) << "fp32 after " << precision;
  }
}

// A model loaded with conv "winograd" runs its 3x3 convolutions so, as `egopd predict --conv winograd` does, and a
// model loaded with conv NULL afterwards is back at the default (auto: the tiny model's few channels take direct).
TEST_F(Api, ConvIsTheModels) {
  const std::string video = (root / "frames").string();
  const std::string got = own_model_csv(nullptr, "winograd");
  EXPECT_EQ(got, cli_taxels("--video " + video + " --seed 3 --conv winograd"));
  EXPECT_NE(got, cli_taxels("--video " + video + " --seed 3 --conv direct"));
  egopd_predict_options o = options();
  o.video = video.c_str();
  o.seed = 3;
  EXPECT_EQ(predict_csv(o), cli_taxels("--video " + video + " --seed 3")) << "default after winograd";
}

TEST_F(Api, FramesAndMasksFromMemoryMatchTheCommand) {
  egopd_predict_options o = options();
  use_memory_frames(o);
  o.masks = masks.data();
  o.masks_bytes = masks.size();
  o.masks_count = 2, o.masks_height = H, o.masks_width = W;
  o.prompt = "a hand grasping a can";
  o.seed = 11;
  const std::string want = cli_taxels("--video " + (root / "frames").string() + " --masks " +
                                      (root / "masks").string() + " --seed 11 --prompt 'a hand grasping a can'");
  ASSERT_FALSE(want.empty());
  EXPECT_EQ(predict_csv(o), want);
}

TEST_F(Api, ResultArraysAndOutputFolder) {
  egopd_predict_options o = options();
  use_memory_frames(o);
  o.meta_json = R"({"obj_name": "a CocaCola", "weight": 355, "material": "aluminum"})";
  const std::string out = (root / "api_out").string();
  o.out_dir = out.c_str();
  egopd_result* r = nullptr;
  ASSERT_EQ(egopd_predict(model, &o, &r), EGOPD_OK) << egopd_last_error();
  EXPECT_EQ(egopd_result_frames(r), 2);
  EXPECT_EQ(egopd_result_size(r), 64);
  EXPECT_EQ(egopd_result_num_taxels(r), 162);
  EXPECT_EQ(read(fs::path(out) / "taxels.csv"), taxels_csv(r));
  EXPECT_EQ(read(fs::path(out) / "taxels.csv"),
            cli_taxels("--video " + (root / "frames").string() + " --meta " + (root / "meta.json").string()));
  EXPECT_TRUE(fs::exists(fs::path(out) / "heatmap_001.png"));
  EXPECT_TRUE(fs::exists(fs::path(out) / "summary.json"));
  EXPECT_NE(std::string(egopd_result_summary_json(r)).find("\"prompt\""), std::string::npos);
  for (int64_t f = 0; f < 2; ++f) {
    double sum = 0;
    for (int m = 0; m < 162; ++m) sum += egopd_result_taxels(r)[f * 162 + m];
    EXPECT_DOUBLE_EQ(egopd_result_total_force(r)[f], sum);
    for (int64_t i = 0; i < 64 * 64; ++i) {
      const float h = egopd_result_heatmaps(r)[f * 64 * 64 + i];
      ASSERT_TRUE(h >= 0 && h <= 1) << h;
    }
  }
  egopd_result_free(r);
}

TEST_F(Api, CounterfactualMatchesTheCommand) {
  egopd_predict_options o = options();
  const std::string video = (root / "frames").string(), meta = (root / "meta.json").string();
  o.video = video.c_str();
  o.meta_path = meta.c_str();
  const char* values[] = {"1000", "omit"};
  egopd_result* r[2] = {nullptr, nullptr};
  ASSERT_EQ(egopd_counterfactual(model, &o, "weight", values, 2, r), EGOPD_OK) << egopd_last_error();
  const fs::path out = root / "cli_cf";
  ASSERT_EQ(cli("counterfactual --model " + (root / "model").string() + kCommon + " --video " + video + " --meta " +
                meta + " --vary weight=1000,omit --out " + out.string()),
            0)
      << read(root / "cli.log");
  EXPECT_EQ(std::string(egopd_result_variant_folder(r[0])), "weight_1000g");
  EXPECT_EQ(std::string(egopd_result_variant_value(r[1])), "omit");
  EXPECT_EQ(taxels_csv(r[0]), read(out / "weight_1000g" / "taxels.csv"));
  EXPECT_EQ(taxels_csv(r[1]), read(out / "weight_omit" / "taxels.csv"));
  egopd_result_free(r[0]);
  egopd_result_free(r[1]);
}

// One line naming what is wrong, the given status, and no result.
void expect_error(egopd_status got, egopd_status want, const std::string& needle, egopd_result* r = nullptr) {
  EXPECT_EQ(got, want) << egopd_last_error();
  const std::string msg = egopd_last_error();
  EXPECT_NE(msg.find(needle), std::string::npos) << msg;
  EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
  EXPECT_EQ(r, nullptr);
}

TEST_F(Api, BadInputIsAnErrorNeverACrash) {
  egopd_result* r = nullptr;
  egopd_predict_options o = options();
  expect_error(egopd_predict(nullptr, &o, &r), EGOPD_ERROR_ARGUMENT, "model: null handle", r);
  expect_error(egopd_predict(model, &o, nullptr), EGOPD_ERROR_ARGUMENT, "result: null pointer");

  use_memory_frames(o);
  o.frames_bytes -= 1;
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "frames: buffer of 138239 bytes", r);
  o = options();
  o.frames_count = 3;  // no buffer
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "frames: null buffer", r);
  o = options();
  use_memory_frames(o);
  o.masks = masks.data();
  o.masks_bytes = masks.size();
  o.masks_count = 2, o.masks_height = W, o.masks_width = 0;
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "masks: count, height and width", r);
  o.masks_width = W, o.num_frames = 3;  // 2 masks for 3 sampled frames of 5
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR, "2 mask images but 3 sampled frames", r);

  o = options();
  o.steps = 5000;
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "--steps must be between 1 and 1000", r);
  o = options();
  o.video = "/nonexistent/clip.mp4";
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "/nonexistent/clip.mp4", r);
  o = options();
  o.prompt = "x";
  o.meta_json = "{}";
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "either --prompt or --meta", r);
  o = options();
  o.meta_json = "{\"weight\": ";
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "meta_json: metadata is not valid JSON", r);
  o = options();
  o.struct_size = sizeof o + 8;
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "struct_size", r);
  o = options();
  o.sampler = "ddim";
  expect_error(egopd_predict(model, &o, &r), EGOPD_ERROR_ARGUMENT, "--sampler must be euler or lcm", r);

  egopd_result* cf[1] = {nullptr};
  o = options();
  const char* values[] = {"1"};
  expect_error(egopd_counterfactual(model, &o, "colour", values, 1, cf), EGOPD_ERROR_ARGUMENT, "unknown field 'colour'");
  expect_error(egopd_counterfactual(model, &o, "weight", nullptr, 1, cf), EGOPD_ERROR_ARGUMENT, "values: null");

  egopd_model* m = nullptr;
  egopd_load_options lo;
  egopd_load_options_init(&lo);
  lo.precision = "fp16";
  expect_error(egopd_model_load((root / "model").c_str(), &lo, &m), EGOPD_ERROR_ARGUMENT,
               "precision 'fp16': expected fp32, bf16 or int8");
  EXPECT_EQ(m, nullptr);
  lo.precision = "fp32";
  lo.conv = "fft";
  expect_error(egopd_model_load((root / "model").c_str(), &lo, &m), EGOPD_ERROR_ARGUMENT,
               "conv 'fft': expected direct, winograd or auto");
  EXPECT_EQ(m, nullptr);
  lo.conv = nullptr;
  for (int64_t mb : {int64_t(-2), int64_t(1048577)}) {
    lo.block_cache_mb = mb;
    expect_error(egopd_model_load((root / "model").c_str(), &lo, &m), EGOPD_ERROR_ARGUMENT,
                 "--block-cache-mb must be between 0 and 1048576 (or -1: the default), got " + std::to_string(mb));
    EXPECT_EQ(m, nullptr);
  }
  lo.block_cache_mb = -1;
  expect_error(egopd_model_load((root / "frames").c_str(), &lo, &m), EGOPD_ERROR, "not a model directory");
  expect_error(egopd_model_load((root / "missing").c_str(), &lo, &m), EGOPD_ERROR_ARGUMENT, "does not exist");
  lo.size = 96;
  expect_error(egopd_model_load((root / "model").c_str(), &lo, &m), EGOPD_ERROR_ARGUMENT, "--size");
  expect_error(egopd_model_load((root / "model").c_str(), &lo, nullptr), EGOPD_ERROR_ARGUMENT, "null pointer");

  // The model is still fine after all of that.
  o = options();
  o.video = nullptr;
  EXPECT_FALSE(predict_csv(o).empty());
}

struct CancelAt {
  int step;
  std::vector<std::string> seen;
};
int cancel_at(void* user, const egopd_progress* p) {
  auto* c = static_cast<CancelAt*>(user);
  c->seen.push_back(std::string(p->stage) + (p->steps ? " " + std::to_string(p->step) + "/" + std::to_string(p->steps) : ""));
  return std::string(p->stage) == "denoise" && p->step == c->step;
}

TEST_F(Api, ProgressReportsStagesAndCancelLeavesTheModelUsable) {
  egopd_predict_options o = options();
  const std::string video = (root / "frames").string(), out = (root / "cancelled").string();
  o.video = video.c_str();
  o.seed = 3;
  o.out_dir = out.c_str();
  CancelAt c{1, {}};
  o.progress = cancel_at;
  o.progress_user = &c;
  egopd_result* r = nullptr;
  expect_error(egopd_predict(model, &o, &r), EGOPD_CANCELLED, "cancelled by the progress callback at denoise step 1 of 2",
               r);
  EXPECT_FALSE(fs::exists(out));  // nothing half-written
  for (const auto& e : fs::directory_iterator(root))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();

  c = CancelAt{-1, {}};  // never cancels: the next call on the same model gives the command's taxels
  ASSERT_EQ(egopd_predict(model, &o, &r), EGOPD_OK) << egopd_last_error();
  EXPECT_EQ(taxels_csv(r), cli_taxels("--video " + video + " --seed 3"));
  egopd_result_free(r);
  const std::vector<std::string> want = {"encode", "denoise 1/2", "denoise 2/2", "decode", "write"};
  EXPECT_EQ(c.seen, want);
}

// The block cache limit (process-wide) at each progress report of a call.
int record_block_cache_limit(void* user, const egopd_progress*) {
  static_cast<std::vector<size_t>*>(user)->push_back(egopd::block_cache_limit());
  return 0;
}

// Each model's block_cache_mb holds during its own calls, whichever model ran before; a low_mem model keeps none.
// (Nothing to restore after it: every call sets its model's limit.)
TEST_F(Api, BlockCacheLimitFollowsTheModelOfEachCall) {
  const auto load = [](int64_t mb, int low_mem) {
    return own_model([&](egopd_load_options& lo) {
      EXPECT_EQ(lo.block_cache_mb, -1);  // the default: EGOPD_BLOCK_CACHE_MB, else 1024
      lo.block_cache_mb = mb, lo.low_mem = low_mem;
    });
  };
  egopd_model* const three = load(3, 0);
  egopd_model* const none = load(0, 0);
  egopd_model* const low_mem = load(64, 1);
  ASSERT_TRUE(three && none && low_mem);
  for (auto [m, want] : {std::pair{three, size_t(3) << 20}, std::pair{none, size_t(0)},
                         std::pair{three, size_t(3) << 20}, std::pair{low_mem, size_t(0)}}) {
    std::vector<size_t> seen;
    egopd_predict_options o = options();
    o.progress = record_block_cache_limit;
    o.progress_user = &seen;
    egopd_result* r = nullptr;
    ASSERT_EQ(egopd_predict(m, &o, &r), EGOPD_OK) << egopd_last_error();
    egopd_result_free(r);
    ASSERT_FALSE(seen.empty());
    for (size_t limit : seen) EXPECT_EQ(limit, want);
  }
  for (egopd_model* m : {three, none, low_mem}) egopd_model_free(m);
}

struct Reentry {
  egopd_model* model;
  egopd_status status = EGOPD_OK;
  std::string message;
};
int call_again(void* user, const egopd_progress*) {
  auto* e = static_cast<Reentry*>(user);
  egopd_predict_options o;
  egopd_predict_options_init(&o);
  egopd_result* r = nullptr;
  e->status = egopd_predict(e->model, &o, &r);
  e->message = egopd_last_error();
  egopd_result_free(r);
  return 1;
}

TEST_F(Api, PredictFromInsideTheCallbackIsRefused) {
  egopd_predict_options o = options();
  Reentry e{model, EGOPD_OK, {}};
  o.progress = call_again;
  o.progress_user = &e;
  egopd_result* r = nullptr;
  EXPECT_EQ(egopd_predict(model, &o, &r), EGOPD_CANCELLED);
  EXPECT_EQ(e.status, EGOPD_ERROR_ARGUMENT);
  EXPECT_NE(e.message.find("cannot be called from inside a progress or log callback"), std::string::npos) << e.message;
}

TEST_F(Api, TwoThreadsOnOneModel) {
  const std::string video = (root / "frames").string();
  const std::string want3 = cli_taxels("--video " + video + " --seed 3"), want5 = cli_taxels("--video " + video + " --seed 5");
  std::string got3, got5;
  const auto run = [&](uint64_t seed, std::string* out) {
    for (int k = 0; k < 2; ++k) {
      egopd_predict_options o = options();
      o.video = video.c_str();
      o.seed = seed;
      *out = predict_csv(o);
      if (out->empty()) return;
    }
  };
  std::thread a(run, 3, &got3), b(run, 5, &got5);
  a.join();
  b.join();
  EXPECT_EQ(got3, want3);
  EXPECT_EQ(got5, want5);
  EXPECT_NE(want3, want5);
}

TEST_F(Api, AnotherSizeReloadsTheModel) {
  egopd_predict_options o = options();
  const std::string video = (root / "frames").string();
  o.video = video.c_str();
  o.size = 128;
  egopd_result* r = nullptr;
  ASSERT_EQ(egopd_predict(model, &o, &r), EGOPD_OK) << egopd_last_error();
  EXPECT_EQ(egopd_result_size(r), 128);
  egopd_result_free(r);
  o.size = 64;
  o.seed = 3;
  EXPECT_EQ(predict_csv(o), cli_taxels("--video " + video + " --seed 3"));
}

// 50 predictions on one model: memory stays flat after the first few (arenas reach their size on the first run),
// judged like the batch runner's fifty clips (tests/batch/batch_test.cpp, memory_growth.h): the heap in use must not
// grow after a warm-up (leaking one 3 x 64 x 64 float frame per prediction shows up as ~2 MB), and outside
// AddressSanitizer the resident set's floor neither. Under AddressSanitizer the resident set also holds the
// quarantine of freed blocks, so only the heap count (the sanitizer allocator's) is judged there.
TEST_F(Api, FiftyPredictionsDoNotGrow) {
  egopd_predict_options o = options();
  use_memory_frames(o);
  o.steps = 1;
  const int predictions = 50, warm_up = 10;
  std::vector<int64_t> heap, rss;
  for (int k = 0; k < predictions; ++k) {
    o.seed = uint64_t(k);
    egopd_result* r = nullptr;
    ASSERT_EQ(egopd_predict(model, &o, &r), EGOPD_OK) << egopd_last_error();
    egopd_result_free(r);
    heap.push_back(int64_t(heap_in_use_bytes()));
    rss.push_back(int64_t(current_rss_bytes()));
  }
  EXPECT_GT(heap.back(), 0) << "no heap count on this platform";
  const int64_t heap_growth = heap.back() - heap[warm_up - 1];
  EXPECT_LT(heap_growth, 512 << 10) << "the heap in use grew by " << heap_growth << " bytes over "
                                    << predictions - warm_up << " predictions";
#if !EGOPD_ADDRESS_SANITIZER
  const int64_t floor_growth = testing_memory::rss_floor_growth(rss, 10, 40);
  EXPECT_LT(floor_growth, 3 << 20) << "the resident set's floor grew by " << floor_growth
                                   << " bytes from predictions 11-20 to 41-50; per prediction from 11:"
                                   << testing_memory::steps_from(rss, 10);
#endif
}

// Blocks stay cached between calls while a model exists; freeing the last model gives them back. Models of its own at
// 256 x 256 (the Api suite's 64 x 64 activations are below the cache's 1 MiB blocks), run after that suite freed its.
TEST(ApiLastModel, FreeingItEmptiesTheBlockCache) {
  const fs::path dir = fs::temp_directory_path() / ("egopd_api_last_model_" + std::to_string(::getpid()));
  write_synthetic_model(dir.string(), "tiny", 7, DType::F32, 0);
  egopd_load_options lo;
  egopd_load_options_init(&lo);
  lo.threads = 2;
  lo.block_cache_mb = 256;  // not the default, which is 0 under AddressSanitizer
  egopd_model *first = nullptr, *second = nullptr;
  ASSERT_EQ(egopd_model_load(dir.c_str(), &lo, &first), EGOPD_OK) << egopd_last_error();
  ASSERT_EQ(egopd_model_load(dir.c_str(), &lo, &second), EGOPD_OK) << egopd_last_error();
  egopd_predict_options o;
  egopd_predict_options_init(&o);
  o.num_frames = 2, o.steps = 1;
  egopd_result* r = nullptr;
  ASSERT_EQ(egopd_predict(first, &o, &r), EGOPD_OK) << egopd_last_error();
  egopd_result_free(r);
  const size_t cached = block_cache_stats().cached_bytes;
  EXPECT_GT(cached, size_t(0)) << "no block was cached: the test would prove nothing";
  egopd_model_free(first);
  EXPECT_EQ(block_cache_stats().cached_bytes, cached) << "freeing a model while another lives keeps the cache";
  egopd_model_free(second);
  EXPECT_EQ(block_cache_stats().cached_bytes, size_t(0));
  EXPECT_EQ(block_cache_limit(), size_t(256) << 20);  // the limit stays
  fs::remove_all(dir);
}

}  // namespace
}  // namespace egopd
