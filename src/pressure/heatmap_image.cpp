#include "pressure/heatmap_image.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "pressure/renderer.h"

namespace egopd {
namespace {

// Control points of the colour map (position, r, g, b); linear interpolation in between.
struct Stop {
  double t;
  double r, g, b;
};
constexpr Stop kStops[] = {
    {0.00, 10, 10, 60}, {0.25, 90, 30, 140}, {0.50, 200, 40, 80}, {0.75, 245, 140, 30}, {1.00, 255, 245, 180},
};

uint8_t to_byte(double v) { return uint8_t(std::clamp(std::lround(v), 0L, 255L)); }

void put(std::vector<uint8_t>& img, int size, int i, int j, const std::array<uint8_t, 3>& c, ChannelOrder order) {
  if (i < 0 || j < 0 || i >= size || j >= size) return;
  uint8_t* px = img.data() + (size_t(i) * size + j) * 3;
  const bool bgr = order == ChannelOrder::BGR;
  px[0] = bgr ? c[2] : c[0];
  px[1] = c[1];
  px[2] = bgr ? c[0] : c[2];
}

}  // namespace

std::array<uint8_t, 3> pressure_colour(double t) {
  t = std::isfinite(t) ? std::clamp(t, 0.0, 1.0) : 0.0;
  const int n = int(std::size(kStops));
  int k = 0;
  while (k + 2 < n && t > kStops[k + 1].t) ++k;
  const Stop& a = kStops[k];
  const Stop& b = kStops[k + 1];
  const double u = (t - a.t) / (b.t - a.t);
  return {to_byte(a.r + u * (b.r - a.r)), to_byte(a.g + u * (b.g - a.g)), to_byte(a.b + u * (b.b - a.b))};
}

std::vector<uint8_t> paint_heatmap(const std::vector<double>& h, int size, const std::vector<Point2>& outline,
                                   const HeatmapPaintOptions& opt) {
  if (h.size() != size_t(size) * size) throw Error("paint_heatmap: heatmap is not " + std::to_string(size) + "x" + std::to_string(size));
  if (!(opt.vmax > 0) || !std::isfinite(opt.vmax)) throw Error("paint_heatmap: vmax must be finite and > 0");
  for (size_t k = 0; k < h.size(); ++k)  // NaN must never be drawn as "no pressure"
    if (!std::isfinite(h[k])) throw Error("paint_heatmap: non-finite heatmap value at pixel " + std::to_string(k));
  std::vector<uint8_t> img(h.size() * 3);
  for (int i = 0; i < size; ++i)
    for (int j = 0; j < size; ++j) {
      const bool on_hand = outline.size() < 3 || inside_polygon(outline, j, i);
      put(img, size, i, j, on_hand ? pressure_colour(h[size_t(i) * size + j] / opt.vmax) : opt.background, opt.order);
    }
  if (!opt.draw_outline || outline.size() < 2) return img;
  // Each edge sampled at half-pixel steps: dense enough for a connected 1-px line.
  for (size_t k = 0; k < outline.size(); ++k) {
    const Point2 a = outline[k], b = outline[(k + 1) % outline.size()];
    const int steps = std::max(1, int(std::ceil(2 * std::hypot(b.x - a.x, b.y - a.y))));
    for (int s = 0; s <= steps; ++s) {
      const double u = double(s) / steps;
      put(img, size, int(std::lround(a.y + u * (b.y - a.y))), int(std::lround(a.x + u * (b.x - a.x))), opt.outline,
          opt.order);
    }
  }
  return img;
}

}  // namespace egopd
