// Low-memory mode (components loaded one at a time, CLIP, U-Net and VAE-decoder weights paged out layer by layer,
// the VAE's temporal layers tiled with their first convolution recomputed) gives the results of normal mode on a
// tiny synthetic model at 64 x 64: the same latents, decoded frames and taxels, with the default whole-clip decode and
// with a chunked one (chunking itself changes the decoded frames, vae.md §5.2, equally in both modes). One and two
// threads give the same results too (only the float summation order differs).
// WeightMap::release covers exactly the tensors under a prefix and leaves their data readable.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/block_pool.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "core/threading.h"
#include "core/weights.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/predict_run.h"
#include "pipeline/synthetic_model.h"
#include "reused_blocks.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

constexpr int64_t kFrames = 3, kSize = 64;
// The golden tolerance of the pipeline's latents (svd_pipeline case); taxels are normalised to [0, 1].
constexpr double kLatentMaxAbs = 1.96e-3, kTaxelMaxAbs = 1e-5;

class PipelineModes : public ::testing::Test {
 protected:
  static fs::path root;
  static void SetUpTestSuite() {
    root = fs::temp_directory_path() / ("egopd_low_mem_test_" + std::to_string(::getpid()));
    fs::remove_all(root);
    write_synthetic_model((root / "model").string(), "tiny", 3, DType::F32, 0);
  }
  static void TearDownTestSuite() { fs::remove_all(root); }

  struct Run {
    EgoPressureDiffPipeline::Result result;
    StageTimes times;
  };
  // Two Euler steps with guidance (both halves of the batch), a prompt and hint masks: every component runs.
  static Run run(bool low_mem, int64_t decode_chunk) {
    EgoPressureDiffPipeline pipe((root / "model").string(), kSize, "", low_mem);
    PipelineSettings s = pipe.settings_from_defaults();
    s.frames = kFrames;
    s.steps = 2;
    s.seed = 5;
    s.min_guidance = 1, s.max_guidance = 2.5f;
    s.decode_chunk = decode_chunk;
    const Tensor frames = frames_to_tensor(synthetic_sample_clip(int(kFrames), int(kSize)));
    Tensor masks({kFrames, 1, kSize, kSize});
    for (int64_t i = 0; i < masks.numel(); ++i) masks[i] = (i / 7) % 3 == 0 ? 1.0f : 0.0f;
    Run r;
    const Tensor text =
        pipe.encode_text(pipe.prompt_for({{"obj_name", "a mug"}, {"weight", "355g"}}), nullptr, &r.times);
    const auto sh = pipe.encode(frames, &masks, s, &r.times);
    r.result = pipe.run(sh, text, s, nullptr, &r.times);
    return r;
  }
};
fs::path PipelineModes::root;

double max_abs_diff(const Tensor& a, const Tensor& b) {
  EXPECT_TRUE(a.shape() == b.shape()) << a.shape().str() << " vs " << b.shape().str();
  double m = 0;
  for (int64_t i = 0; i < a.numel(); ++i) m = std::max(m, std::abs(double(a[i]) - double(b[i])));
  return m;
}

double taxel_max_abs_diff(const EgoPressureDiffPipeline::Result& a, const EgoPressureDiffPipeline::Result& b) {
  EXPECT_EQ(a.frames.size(), b.frames.size());
  double m = 0;
  for (size_t f = 0; f < a.frames.size(); ++f) {
    EXPECT_EQ(a.frames[f].p.size(), b.frames[f].p.size());
    for (size_t k = 0; k < a.frames[f].p.size(); ++k) m = std::max(m, std::abs(a.frames[f].p[k] - b.frames[f].p[k]));
  }
  return m;
}

bool has_stage(const StageTimes& t, const std::string& name) {
  for (const auto& [k, v] : t.entries())
    if (k == name) return true;
  return false;
}

TEST_F(PipelineModes, LowMemMatchesNormalMode) {
  const Run normal = run(false, 0);
  const Run low = run(true, 0);
  EXPECT_LE(max_abs_diff(normal.result.latents, low.result.latents), kLatentMaxAbs);
  EXPECT_LE(taxel_max_abs_diff(normal.result, low.result), kTaxelMaxAbs);
  EXPECT_LE(max_abs_diff(normal.result.decoded, low.result.decoded), kTaxelMaxAbs);
  // Loading happens inside the stages in low-memory mode and is accounted separately.
  EXPECT_TRUE(has_stage(low.times, "load"));
  EXPECT_FALSE(has_stage(normal.times, "load"));
}

TEST_F(PipelineModes, LowMemKeepsNoFreedActivationsResident) {
  const testing_memory::ScopedBlockCacheLimit limit(size_t(64) << 20);
  { Tensor freed(Shape{int64_t(1) << 20}); }  // 4 MiB, cached when it goes
  EXPECT_GT(block_cache_stats().cached_bytes, 0u);
  EgoPressureDiffPipeline normal((root / "model").string(), kSize, "", false);
  EXPECT_EQ(block_cache_limit(), size_t(64) << 20);
  EgoPressureDiffPipeline low((root / "model").string(), kSize, "", true);
  EXPECT_EQ(block_cache_limit(), 0u);
  EXPECT_EQ(block_cache_stats().cached_bytes, 0u);
}

TEST_F(PipelineModes, LowMemChunkedDecodeMatchesNormalModeWithTheSameChunk) {
  const Run normal = run(false, 2);
  const Run low = run(true, 2);
  EXPECT_LE(max_abs_diff(normal.result.latents, low.result.latents), kLatentMaxAbs);
  EXPECT_LE(taxel_max_abs_diff(normal.result, low.result), kTaxelMaxAbs);
  EXPECT_LE(max_abs_diff(normal.result.decoded, low.result.decoded), kTaxelMaxAbs);
}

TEST_F(PipelineModes, OneAndTwoThreadsAgreeInBothModes) {
  for (bool low_mem : {false, true}) {
    set_num_threads(1);
    const Run one = run(low_mem, 0);
    set_num_threads(2);
    const Run two = run(low_mem, 0);
    set_num_threads(0);
    const std::string mode = low_mem ? "low-mem" : "normal";
    EXPECT_LE(max_abs_diff(one.result.latents, two.result.latents), kLatentMaxAbs) << mode;
    EXPECT_LE(max_abs_diff(one.result.decoded, two.result.decoded), kTaxelMaxAbs) << mode;
    EXPECT_LE(taxel_max_abs_diff(one.result, two.result), kTaxelMaxAbs) << mode;
  }
}

TEST_F(PipelineModes, PredictWritesLowMemSummary) {
  PredictOptions o;
  o.model_dir = (root / "model").string();
  o.frames = 2;
  o.size = kSize;
  o.steps = 2;
  o.low_mem = true;
  o.out_dir = (root / "predict").string();
  ASSERT_EQ(run_predict(o), 0);
  std::ifstream in(root / "predict" / "summary.json");
  const nlohmann::json j = parse_json(in);
  EXPECT_TRUE(j["low_mem"].get<bool>());
  EXPECT_EQ(j["decode_chunk"].get<int64_t>(), o.frames);  // the whole clip in one decode, as in normal mode
  EXPECT_TRUE(fs::exists(root / "predict" / "taxels.csv"));
}

TEST(WeightMapRelease, CoversExactlyThePrefixAndKeepsDataReadable) {
  const fs::path file = fs::temp_directory_path() / ("egopd_release_test_" + std::to_string(::getpid()) + ".safetensors");
  // Large enough that each tensor spans whole pages, so madvise really drops some.
  const int64_t n = 1 << 16;
  Tensor a({n}), b({n}), c({n});
  for (int64_t i = 0; i < n; ++i) a[i] = float(i), b[i] = float(-i), c[i] = 0.5f * float(i);
  write_safetensors(file.string(), {to_write("blocks.1.w", a), to_write("blocks.10.w", b), to_write("blocks.1", c)});
  {
    const WeightMap m = WeightMap::load_file(file.string(), "test");
    const Tensor before = m.find("blocks.1.w")->to_f32();
    EXPECT_EQ(m.release("blocks.1"), uint64_t(2 * n * 4));  // blocks.1 and blocks.1.w, not blocks.10.w
    EXPECT_EQ(m.release("blocks.10"), uint64_t(n * 4));
    EXPECT_EQ(m.release(""), m.total_bytes());
    EXPECT_EQ(m.release("block"), 0u);  // a prefix is a whole key path component
    const Tensor after = m.find("blocks.1.w")->to_f32();  // re-read from the file
    EXPECT_EQ(max_abs_diff(before, after), 0.0);
  }
  fs::remove(file);
}

}  // namespace
}  // namespace egopd
