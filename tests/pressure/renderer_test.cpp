// Canvas fit, hand mask V, operator A, ridge inverse and the post-processing steps (pressure.md §4-§7), checked
// against hand-computed small cases and properties.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/error.h"
#include "pressure/normalization.h"
#include "pressure/renderer.h"

namespace egopd {
namespace {

// Unit-square hand. At S = 16: μ = round(0.5) = 1, E = 13, s = 13, offsets 1: canvas square [1, 14]², so V holds
// pixel centres with 1 <= x, y < 14 (even-odd rule: left/top edges in, right/bottom out) -> 13 × 13 = 169 pixels.
HandTemplate square(const std::vector<Point2>& grid_sensors) {
  std::vector<Sensor> s;
  for (const auto& g : grid_sensors) s.push_back({int(s.size()), g, Region::Palm});
  return HandTemplate::from_parts("square", s, {{0, 0}, {1, 0}, {1, 1}, {0, 1}}, true);
}
Point2 grid_of_canvas(double x, double y) { return {(x - 1) / 13, (y - 1) / 13}; }  // inverse of the S = 16 fit

TEST(CanvasFit, HandComputed) {
  const CanvasFit f = CanvasFit::fit({{0, 0}, {10, 0}, {10, 5}, {0, 5}}, 256);
  EXPECT_EQ(f.margin, 8);
  EXPECT_DOUBLE_EQ(f.scale, 23.9);          // 239 / 10
  EXPECT_DOUBLE_EQ(f.offset_x, 8.0);        // 8 + (239 - 239)/2 - 0
  EXPECT_DOUBLE_EQ(f.offset_y, 67.75);      // 8 + (239 - 119.5)/2
  const Point2 c = f.to_canvas({10, 5});
  EXPECT_DOUBLE_EQ(c.x, 247.0);
  EXPECT_DOUBLE_EQ(c.y, 187.25);
  const CanvasFit g = CanvasFit::fit({{-2, 1}, {2, 1}, {0, 9}}, 64);  // W 4, H 8: μ 2, E 59, s 7.375
  EXPECT_EQ(g.margin, 2);
  EXPECT_DOUBLE_EQ(g.scale, 7.375);
  EXPECT_DOUBLE_EQ(g.offset_x, 2 + (59 - 29.5) / 2 + 2 * 7.375);
  EXPECT_DOUBLE_EQ(g.offset_y, 2 - 7.375);
  EXPECT_THROW(CanvasFit::fit({{1, 1}, {1, 1}, {1, 1}}, 64), Error);
}

TEST(InsidePolygon, EvenOddHalfOpen) {
  const std::vector<Point2> sq = {{0, 0}, {4, 0}, {4, 4}, {0, 4}};
  EXPECT_TRUE(inside_polygon(sq, 2, 2));
  EXPECT_FALSE(inside_polygon(sq, 5, 2));
  EXPECT_TRUE(inside_polygon(sq, 0, 2));   // left edge in
  EXPECT_FALSE(inside_polygon(sq, 4, 2));  // right edge out
  EXPECT_TRUE(inside_polygon(sq, 2, 0));   // top edge in
  EXPECT_FALSE(inside_polygon(sq, 2, 4));  // bottom edge out
  // A concave "U": the notch is outside.
  const std::vector<Point2> u = {{0, 0}, {1, 0}, {1, 3}, {2, 3}, {2, 0}, {3, 0}, {3, 4}, {0, 4}};
  EXPECT_FALSE(inside_polygon(u, 1.5, 1));
  EXPECT_TRUE(inside_polygon(u, 0.5, 1));
  EXPECT_TRUE(inside_polygon(u, 1.5, 3.5));
}

TEST(RenderParams, ScaleWithCanvas) {
  const RenderParams a = RenderParams{}.resolved(256), b = RenderParams{}.resolved(128), c = RenderParams{}.resolved(512);
  EXPECT_EQ(a.sigma_px, 6.0);
  EXPECT_EQ(a.disk_radius_px, 3.0);
  EXPECT_EQ(a.lambda, 1e-3);
  EXPECT_EQ(a.eps, 1e-8);
  EXPECT_EQ(a.floor_percentile, 5.0);
  EXPECT_EQ(b.sigma_px, 3.0);
  EXPECT_EQ(b.disk_radius_px, 1.5);
  EXPECT_EQ(b.lambda, 2.5e-4);
  EXPECT_EQ(c.sigma_px, 12.0);
  EXPECT_EQ(c.lambda, 4e-3);
  RenderParams d;
  d.lambda = 0.5;
  EXPECT_EQ(d.resolved(128).lambda, 0.5);  // explicit values are kept
}

TEST(Renderer, HandMaskOfSquare) {
  const PressureRenderer r(square({grid_of_canvas(7, 7)}), 16);
  EXPECT_EQ(r.num_hand_pixels(), 169);
  EXPECT_EQ(r.hand_pixels().front(), 1 * 16 + 1);
  EXPECT_EQ(r.hand_pixels().back(), 13 * 16 + 13);
  EXPECT_NEAR(r.sensor_canvas()[0].x, 7.0, 1e-12);
  EXPECT_NEAR(r.sensor_canvas()[0].y, 7.0, 1e-12);
  for (size_t k = 1; k < r.hand_pixels().size(); ++k) EXPECT_LT(r.hand_pixels()[k - 1], r.hand_pixels()[k]);
}

TEST(Renderer, ForwardOperatorEntryByHand) {
  RenderParams p;
  p.sigma_px = 3;
  const PressureRenderer r(square({grid_of_canvas(4.25, 7.5), grid_of_canvas(10.75, 7.5)}), 16, p);
  // Pixel (row 7, column 4): centre (4, 7). d1² = 0.25² + 0.5² = 0.3125, d2² = 6.75² + 0.5² = 45.8125.
  const double w1 = std::exp(-0.3125 / 18), w2 = std::exp(-45.8125 / 18);
  const int row = (7 - 1) * 13 + (4 - 1);  // row-major index of that pixel within V
  ASSERT_EQ(r.hand_pixels()[row], 7 * 16 + 4);
  EXPECT_NEAR(r.forward_operator()(row, 0), w1 / (w1 + w2 + 1e-8), 1e-14);
  EXPECT_NEAR(r.forward_operator()(row, 1), w2 / (w1 + w2 + 1e-8), 1e-14);
  // The pixel column 7.5 would be equidistant; column 7 and 8 mirror each other.
  const int a = (7 - 1) * 13 + (7 - 1), b = (7 - 1) * 13 + (8 - 1);
  EXPECT_NEAR(r.forward_operator()(a, 0), r.forward_operator()(b, 1), 1e-14);
}

TEST(Renderer, RowsSumToOne) {
  // A row sums to Σw/(Σw + ε), i.e. 1 up to ε/Σw: negligible wherever a sensor is within a few σ. An octagon
  // with a 5 × 4 sensor grid 2 units (≈ 10 px) apart and σ = 6 px.
  std::vector<Sensor> sensors;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 4; ++j) sensors.push_back({int(sensors.size()), {2.0 + 2 * j, 2.0 + 2 * i}, Region::Palm});
  const HandTemplate t = HandTemplate::from_parts(
      "oct", sensors, {{2, 0}, {8, 0}, {10, 2}, {10, 10}, {8, 12}, {2, 12}, {0, 10}, {0, 2}}, true);
  RenderParams params;
  params.sigma_px = 6;
  const PressureRenderer r(t, 64, params);
  const Eigen::VectorXd sums = r.forward_operator().rowwise().sum();
  EXPECT_LT((sums.array() - 1.0).abs().maxCoeff(), 1e-6);
  EXPECT_GE(r.forward_operator().minCoeff(), 0.0);
  // Uniform p renders as that value over V and 0 elsewhere.
  const std::vector<double> h = r.render(std::vector<double>(20, 0.3));
  std::vector<bool> in_v(64 * 64, false);
  for (int p : r.hand_pixels()) in_v[p] = true;
  for (int k = 0; k < 64 * 64; ++k) {
    if (in_v[k])
      EXPECT_NEAR(h[k], 0.3, 0.3e-6);
    else
      EXPECT_EQ(h[k], 0.0);
  }
}

TEST(Renderer, RowsSumToOneOnShippedTemplate) {
  // Default constants at S = 128 (σ = 3 px): the farthest hand pixel from any taxel still has Σw >= 2.5e-4, so
  // the row sums are within 1e-8/2.5e-4 = 4e-5 of 1.
  const HandTemplate t = HandTemplate::load(std::string(EGOPD_TEST_DATA) + "/../data/templates/synthetic_right_hand.json");
  const PressureRenderer r(t, 128);
  const Eigen::VectorXd sums = r.forward_operator().rowwise().sum();
  EXPECT_LT((sums.array() - 1.0).abs().maxCoeff(), 4e-5);
  EXPECT_LE(sums.maxCoeff(), 1.0);
}

TEST(Renderer, RidgeOneSensorByHand) {
  // One sensor, ε = 0: every row of A is exactly 1, so p̂ = Σh / (N_V + λ). With λ = N_V = 169, p̂ = mean(h)/2.
  RenderParams p;
  p.eps = 0;
  p.lambda = 169;
  const PressureRenderer r(square({grid_of_canvas(7, 7)}), 16, p);
  for (int k = 0; k < r.num_hand_pixels(); ++k) ASSERT_EQ(r.forward_operator()(k, 0), 1.0);
  const std::vector<double> h = r.render({0.8});
  EXPECT_NEAR(r.ridge_solve(h)[0], 0.4, 1e-12);
  std::vector<double> g(256, 0.0);
  for (int k = 0; k < r.num_hand_pixels(); ++k) g[r.hand_pixels()[k]] = k % 2;  // 84 ones on V (odd k of 0..168)
  g[0] = 100;  // off V: ignored
  EXPECT_NEAR(r.ridge_solve(g)[0], 84.0 / 338.0, 1e-12);
}

TEST(Renderer, RidgeRecoversPWhenLambdaVanishes) {
  // Four well-separated sensors: AᵀA is well conditioned, so λ -> 0 inverts the rendering exactly.
  RenderParams params;
  params.lambda = 1e-12;
  params.sigma_px = 3;
  const PressureRenderer r(square({{0.2, 0.2}, {0.8, 0.2}, {0.2, 0.8}, {0.8, 0.8}}), 32, params);
  const std::vector<double> p = {0.1, 0.7, 0.0, 1.0};
  const std::vector<double> q = r.ridge_solve(r.render(p));
  for (int m = 0; m < 4; ++m) EXPECT_NEAR(q[m], p[m], 1e-8);
  // The explicit Rg gives the same product.
  const Eigen::MatrixXd rg = r.ridge_inverse();
  ASSERT_EQ(rg.rows(), 4);
  ASSERT_EQ(rg.cols(), r.num_hand_pixels());
  const std::vector<double> h = r.render(p);
  Eigen::VectorXd hv(r.num_hand_pixels());
  for (int k = 0; k < r.num_hand_pixels(); ++k) hv[k] = h[r.hand_pixels()[k]];
  const Eigen::VectorXd q2 = rg * hv;
  for (int m = 0; m < 4; ++m) EXPECT_NEAR(q2[m], q[m], 1e-10);
  // Ridge shrinks: with a large λ the estimate moves towards 0 but keeps the sign pattern.
  params.lambda = 1e3;
  const PressureRenderer strong(square({{0.2, 0.2}, {0.8, 0.2}, {0.2, 0.8}, {0.8, 0.8}}), 32, params);
  const std::vector<double> s = strong.ridge_solve(strong.render(p));
  EXPECT_LT(s[3], 0.9);
  EXPECT_GT(s[3], 0.0);
}

TEST(PostProcess, ImageToHeatmap) {
  const PressureRenderer r(square({grid_of_canvas(7, 7)}), 16);
  std::vector<float> y(3 * 256, -1.0f);
  auto set = [&](int k, float a, float b, float c) { y[k] = a, y[256 + k] = b, y[512 + k] = c; };
  set(1, 1, 0, -0.5f);   // mean 1/6 -> 7/12
  set(2, 1, 1, 1);       // -> 1
  set(3, 2, 2, 2);       // clamp -> 1
  set(4, -3, -3, -3);    // clamp -> 0
  set(5, 0.5f, 0.5f, -1);  // mean 0 -> 0.5
  const std::vector<double> h = r.heatmap_from_image(y.data());
  EXPECT_EQ(h[0], 0.0);
  EXPECT_NEAR(h[1], 7.0 / 12.0, 1e-15);
  EXPECT_EQ(h[2], 1.0);
  EXPECT_EQ(h[3], 1.0);
  EXPECT_EQ(h[4], 0.0);
  EXPECT_EQ(h[5], 0.5);
}

TEST(PostProcess, PercentileFloorByHand) {
  const PressureRenderer r(square({grid_of_canvas(7, 7)}), 16);
  std::vector<double> raw(256, 0.9);  // off-V pixels must end at 0 whatever their value
  for (int k = 0; k < 169; ++k) raw[r.hand_pixels()[168 - k]] = k / 168.0;  // V holds 0/168 .. 168/168
  // pos = 0.05 · 168 = 8.4 -> q = (8 + 0.4·(9 - 8)) / 168.
  const double q = 8.4 / 168.0;
  const std::vector<double> h = r.percentile_floor(raw);
  int off = 0;
  for (int k = 0; k < 256; ++k) off += h[k] == 0.0;
  for (int k = 0; k < 169; ++k) {
    const double v = k / 168.0;
    EXPECT_NEAR(h[r.hand_pixels()[168 - k]], std::max(v - q, 0.0), 1e-15);
  }
  EXPECT_EQ(off, (256 - 169) + 9);  // off V, plus the 9 values <= q
}

TEST(PostProcess, DiskMeansByHand) {
  RenderParams p;
  p.disk_radius_px = 1.5;  // the 3 × 3 block around (7, 7): corners at √2 <= 1.5
  // Second sensor at the canvas corner (14.6, 14.6): no V pixel within 0.4... use r = 1.5: (13,13) is 2.26 away.
  const PressureRenderer r(square({grid_of_canvas(7, 7), grid_of_canvas(14.6, 14.6)}), 16, p);
  std::vector<double> h(256);
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j) h[i * 16 + j] = j + 100.0 * i;
  const std::vector<double> d = r.disk_means(h);
  EXPECT_DOUBLE_EQ(d[0], 707.0);
  EXPECT_EQ(d[1], 0.0);            // empty disk -> 0
  EXPECT_EQ(r.warnings().size(), 1u);  // the corner sensor lies outside V
  // Radius 1: the 5-pixel cross; mean of (7,7),(6,7),(8,7),(7,6),(7,8) = 707 as well, so shift the pattern.
  p.disk_radius_px = 1.0;
  const PressureRenderer r1(square({grid_of_canvas(7, 7)}), 16, p);
  std::vector<double> g(256, 0.0);
  g[7 * 16 + 8] = 5.0;  // one cross pixel
  g[8 * 16 + 8] = 9.0;  // a diagonal pixel, outside radius 1
  EXPECT_DOUBLE_EQ(r1.disk_means(g)[0], 1.0);
}

TEST(PostProcess, ReadoutPipelineConsistency) {
  RenderParams params;
  params.sigma_px = 3;
  const PressureRenderer r(square({{0.2, 0.2}, {0.8, 0.2}, {0.2, 0.8}, {0.8, 0.8}, {0.5, 0.5}}), 32, params);
  const std::vector<double> p = {0.1, 0.7, 0.0, 1.0, 0.4};
  const std::vector<double> h = r.render(p);
  const Tensor img = heatmap_to_image(h, 32);
  const auto f = r.process_frame(img.data());
  // Steps 1-2 by the individual functions; steps 3-6 via Rg·A and via re-render + Rg agree to rounding.
  const std::vector<double> raw = r.heatmap_from_image(img.data());
  EXPECT_EQ(f.h_raw, raw);
  EXPECT_EQ(f.h_norm, r.percentile_floor(raw));
  EXPECT_EQ(f.h_std, r.render(r.disk_means(f.h_norm)));
  const std::vector<double> q = r.readout(f.h_norm);
  for (int m = 0; m < 5; ++m) {
    EXPECT_NEAR(q[m], f.p[m], 1e-9);
    EXPECT_GE(f.p[m], 0.0);
  }
  // An all-zero frame reads out as zero pressure.
  const Tensor blank = heatmap_to_image(std::vector<double>(32 * 32, 0.0), 32);
  for (double v : r.process_frame(blank.data()).p) EXPECT_EQ(v, 0.0);
}

TEST(PostProcess, RectifiesNegativeEstimates) {
  // A heatmap bright between two sensors but dark on one of them: the ridge estimate of the dark sensor goes
  // negative without rectification.
  RenderParams params;
  params.sigma_px = 3;
  params.lambda = 1e-9;
  const PressureRenderer r(square({{0.3, 0.5}, {0.5, 0.5}, {0.7, 0.5}}), 32, params);
  const std::vector<double> h = r.render({1.0, -0.5, 1.0});
  EXPECT_LT(r.ridge_solve(h)[1], -0.4);
  const std::vector<double> q = r.readout(r.percentile_floor(h));
  for (double v : q) EXPECT_GE(v, 0.0);
}

TEST(Prototype, HalfOnTheHand) {
  RenderParams params;
  // σ = 6 px: the hand pixel farthest from the sensors (corner (1, 29), 15.3 px from the nearest sensor at
  // (15.5, 24.2)) still has Σw >= exp(-233.3/72) ≈ 0.039, so h = 0.5·Σw/(Σw + ε) is within 0.5·ε/0.039 ≈ 1.3e-7.
  params.sigma_px = 6;
  const PressureRenderer r(square({{0.2, 0.2}, {0.8, 0.2}, {0.5, 0.8}}), 32, params);
  const std::vector<double> h = r.prototype_heatmap();
  const Tensor img = r.prototype_image();
  ASSERT_EQ(img.shape(), (Shape{1, 3, 32, 32}));
  std::vector<bool> in_v(32 * 32, false);
  for (int p : r.hand_pixels()) in_v[p] = true;
  for (int k = 0; k < 32 * 32; ++k) {
    EXPECT_NEAR(h[k], in_v[k] ? 0.5 : 0.0, 1.3e-7);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(img[c * 1024 + k], in_v[k] ? 0.0f : -1.0f, 1e-6f);
  }
}

}  // namespace
}  // namespace egopd
