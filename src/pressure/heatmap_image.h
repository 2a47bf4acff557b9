#pragma once
// Human-facing pictures of heatmaps: a colour map plus the hand outline, as an 8-bit interleaved buffer ready for
// a PNG writer. (The model's own heatmap images are grey 2H-1, see heatmap_to_image in renderer.h.)
#include <array>
#include <cstdint>
#include <vector>

#include "pressure/hand_template.h"

namespace egopd {

enum class ChannelOrder { RGB, BGR };  // OpenCV's imwrite expects BGR

struct HeatmapPaintOptions {
  double vmax = 1.0;                                 // value mapped to the top of the colour map
  std::array<uint8_t, 3> background = {24, 24, 24};  // pixels outside the outline
  std::array<uint8_t, 3> outline = {255, 255, 255};
  bool draw_outline = true;
  ChannelOrder order = ChannelOrder::RGB;
};

// Colour of t in [0, 1] (clamped): dark blue -> violet -> red -> orange -> light yellow, monotone in lightness.
std::array<uint8_t, 3> pressure_colour(double t);

// S*S heatmap (row-major) -> S*S*3 bytes. `outline_canvas` is the fitted outline (PressureRenderer::
// outline_canvas()); pixels outside it get the background colour, the polygon is drawn on top.
std::vector<uint8_t> paint_heatmap(const std::vector<double>& heatmap, int size,
                                   const std::vector<Point2>& outline_canvas, const HeatmapPaintOptions& opt = {});

}  // namespace egopd
