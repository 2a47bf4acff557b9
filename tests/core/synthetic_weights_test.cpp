// synthetic_weights_id: the cache key of a synthetic weights file changes with every name, shape, dtype and seed, and
// with nothing else.
#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

#include "core/synthetic_weights.h"

namespace egopd {
namespace {

using Params = std::vector<std::pair<std::string, Shape>>;

TEST(SyntheticWeightsId, ChangesWithEveryNameShapeDtypeAndSeed) {
  const Params base = {{"conv_in.weight", Shape{320, 8, 3, 3}}, {"conv_in.bias", Shape{320}}};
  const std::string id = synthetic_weights_id(base, DType::F16, 1234);
  ASSERT_EQ(id.size(), 16u);
  EXPECT_EQ(id.find_first_not_of("0123456789abcdef"), std::string::npos) << id;
  EXPECT_EQ(synthetic_weights_id(base, DType::F16, 1234), id);  // deterministic

  Params renamed = base, reshaped = base, extra = base, split = base;
  renamed[1].first = "conv_in.bias2";
  reshaped[0].second = Shape{320, 8, 3, 1};
  extra.push_back({"conv_out.bias", Shape{4}});
  // The same digits regrouped: "320 8 3 3" against "320 83 3" must differ.
  split[0].second = Shape{320, 83, 3};
  for (const Params& p : {renamed, reshaped, extra, split}) EXPECT_NE(synthetic_weights_id(p, DType::F16, 1234), id);
  EXPECT_NE(synthetic_weights_id(base, DType::F32, 1234), id);
  EXPECT_NE(synthetic_weights_id(base, DType::F16, 1235), id);
}

}  // namespace
}  // namespace egopd
