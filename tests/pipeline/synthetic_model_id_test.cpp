// synthetic_model_id: the cache key of a synthetic model folder (the built-in model's, bench pipeline's) changes with
// the preset, the seed, the dtype and the sampler's step count, and the built-in model's folder is named by it.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "pipeline/predict_run.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace {

TEST(SyntheticModelId, ChangesWithPresetSeedDtypeAndSteps) {
  const std::string id = synthetic_model_id("tiny", 0, DType::F32, 4);
  ASSERT_EQ(id.size(), 16u);
  EXPECT_EQ(id.find_first_not_of("0123456789abcdef"), std::string::npos) << id;
  EXPECT_EQ(synthetic_model_id("tiny", 0, DType::F32, 4), id);  // deterministic
  EXPECT_NE(synthetic_model_id("svd-xt", 0, DType::F32, 4), id);
  EXPECT_NE(synthetic_model_id("tiny", 1, DType::F32, 4), id);
  EXPECT_NE(synthetic_model_id("tiny", 0, DType::F16, 4), id);
  EXPECT_NE(synthetic_model_id("tiny", 0, DType::F32, 0), id);
  EXPECT_NE(synthetic_model_id("tiny", 0, DType::F32, 8), id);
}

TEST(SyntheticModelId, NamesTheBuiltInModelFolder) {
  const std::string name = std::filesystem::path(default_model_dir("out")).filename().string();
  const std::string id = synthetic_model_id("tiny", 0, DType::F32, 4);
  ASSERT_GE(name.size(), id.size() + 1);
  EXPECT_EQ(name.substr(name.size() - id.size() - 1), "-" + id) << name;
}

}  // namespace
}  // namespace egopd
