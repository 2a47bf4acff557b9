// Frame-wise linear guidance scales and the CFG combination, against hand-derived values.
#include "scheduler/guidance.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace egopd {
namespace {

TEST(Guidance, FrameScalesAreLinspace) {
  EXPECT_EQ(frame_guidance_scales(1.0f, 3.0f, 3), (std::vector<float>{1.0f, 2.0f, 3.0f}));
  EXPECT_EQ(frame_guidance_scales(1.0f, 3.0f, 5), (std::vector<float>{1.0f, 1.5f, 2.0f, 2.5f, 3.0f}));
  EXPECT_EQ(frame_guidance_scales(2.5f, 7.0f, 1), (std::vector<float>{2.5f}));
  EXPECT_EQ(frame_guidance_scales(1.0f, 1.0f, 4), (std::vector<float>(4, 1.0f)));
  const auto g = frame_guidance_scales(1.0f, 3.0f, 16);
  ASSERT_EQ(g.size(), 16u);
  EXPECT_EQ(g.front(), 1.0f);
  EXPECT_EQ(g.back(), 3.0f);
  for (int f = 0; f < 16; ++f) EXPECT_NEAR(g[f], 1.0 + 2.0 * f / 15.0, 3e-7) << f;
  EXPECT_THROW(frame_guidance_scales(1.0f, 3.0f, 0), Error);
}

TEST(Guidance, EnabledOnlyAboveOne) {
  EXPECT_FALSE(guidance_enabled(1.0f));
  EXPECT_FALSE(guidance_enabled(0.5f));
  EXPECT_TRUE(guidance_enabled(1.01f));
}

TEST(Guidance, CfgCombinePerFrame) {
  // [B=2, F=3, 2 elements]: v = u + g_f (c - u).
  const std::vector<float> g{1.0f, 2.0f, 3.0f};
  Tensor u = Tensor::from({2, 3, 2}, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11});
  Tensor c = Tensor::full({2, 3, 2}, 1.0f);
  Tensor v = cfg_combine(u, c, g);
  const std::vector<float> want{1, 1, 0, -1, -5, -7, 1, 1, -6, -7, -17, -19};
  EXPECT_EQ(v.to_vector(), want);
  EXPECT_THROW(cfg_combine(u, Tensor::zeros({2, 6}), g), Error);
  EXPECT_THROW(cfg_combine(u, c, {1.0f, 2.0f}), Error);
  // In place into the uncond buffer.
  cfg_combine(u.data(), c.data(), g, 2, 2, u.data());
  EXPECT_EQ(u.to_vector(), want);
}

}  // namespace
}  // namespace egopd
