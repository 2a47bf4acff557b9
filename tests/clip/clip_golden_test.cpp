// The four CLIP golden cases through their runners, compared as compare.py does (ids exactly), at 1 and 2 threads.
#include <gtest/gtest.h>

#include <string>

#include "core/golden.h"
#include "core/threading.h"

namespace egopd {
CaseOutputs run_clip_vision_case(const GoldenCase&);
CaseOutputs run_image_preprocess_case(const GoldenCase&);
CaseOutputs run_clip_text_case(const GoldenCase&);
CaseOutputs run_tokenizer_case(const GoldenCase&);

namespace {

void expect_case_passes(const std::string& name, CaseOutputs (*run)(const GoldenCase&)) {
  const GoldenCase c = load_golden_case(std::string(EGOPD_TEST_DATA) + "/data/golden/" + name);
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    const CaseOutputs out = run(c);
    for (const auto& r : compare_case_outputs(c, out))
      EXPECT_TRUE(r.ok) << name << " (" << threads << " threads) " << r.name << ": max_abs " << r.max_abs << " (tol "
                        << r.tol_max_abs << ") rel_l2 " << r.rel_l2 << " (tol " << r.tol_rel_l2 << ") " << r.message;
  }
  set_num_threads(0);
}

TEST(ClipGolden, ClipVision) { expect_case_passes("clip_vision", run_clip_vision_case); }
TEST(ClipGolden, ClipText) { expect_case_passes("clip_text", run_clip_text_case); }
TEST(ClipGolden, Tokenizer) { expect_case_passes("tokenizer", run_tokenizer_case); }
TEST(ClipGolden, ImagePreprocess) { expect_case_passes("image_preprocess", run_image_preprocess_case); }

}  // namespace
}  // namespace egopd
