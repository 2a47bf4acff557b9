// Colour map and outline painting for human-facing heatmap pictures.
#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "core/error.h"
#include "pressure/heatmap_image.h"

namespace egopd {
namespace {

using Rgb = std::array<uint8_t, 3>;

TEST(PressureColour, ControlPointsAndInterpolation) {
  EXPECT_EQ(pressure_colour(0.0), (Rgb{10, 10, 60}));
  EXPECT_EQ(pressure_colour(0.5), (Rgb{200, 40, 80}));
  EXPECT_EQ(pressure_colour(1.0), (Rgb{255, 245, 180}));
  EXPECT_EQ(pressure_colour(0.125), (Rgb{50, 20, 100}));  // halfway between the first two stops
  EXPECT_EQ(pressure_colour(-3.0), pressure_colour(0.0));  // clamped
  EXPECT_EQ(pressure_colour(7.0), pressure_colour(1.0));
}

TEST(PaintHeatmap, BackgroundHeatAndOutline) {
  const int S = 8;
  std::vector<double> h(S * S, 0.0);
  h[3 * S + 3] = 2.0;  // vmax 2 -> top of the map
  const std::vector<Point2> outline = {{1, 1}, {6, 1}, {6, 6}, {1, 6}};
  HeatmapPaintOptions opt;
  opt.vmax = 2.0;
  opt.draw_outline = false;
  const auto img = paint_heatmap(h, S, outline, opt);
  ASSERT_EQ(img.size(), size_t(S * S * 3));
  auto px = [&](const std::vector<uint8_t>& im, int i, int j) { return Rgb{im[(i * S + j) * 3], im[(i * S + j) * 3 + 1], im[(i * S + j) * 3 + 2]}; };
  EXPECT_EQ(px(img, 0, 0), opt.background);         // off the hand
  EXPECT_EQ(px(img, 3, 3), (Rgb{255, 245, 180}));    // hottest
  EXPECT_EQ(px(img, 2, 2), (Rgb{10, 10, 60}));       // on the hand, zero pressure
  opt.draw_outline = true;
  opt.order = ChannelOrder::BGR;
  const auto bgr = paint_heatmap(h, S, outline, opt);
  EXPECT_EQ(px(bgr, 1, 3), opt.outline);             // on the top edge
  EXPECT_EQ(px(bgr, 3, 3), (Rgb{180, 245, 255}));    // channels swapped
  EXPECT_THROW(paint_heatmap(std::vector<double>(5), S, outline), Error);
}

}  // namespace
}  // namespace egopd
