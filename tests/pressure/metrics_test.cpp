// Metrics on a hand-computed three-frame example (pressure.md §8) and the PressureVision-style pooling.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "core/error.h"
#include "pressure/metrics.h"

namespace egopd {
namespace {

// 0,1: tip_thumb at (0,0),(4,0); 2: tip_index at (10,0); 3-6: palm at (0,10),(4,10),(0,14),(4,14); 7: other.
HandTemplate small_hand() {
  const std::vector<Sensor> s = {
      {0, {0, 0}, Region::TipThumb}, {1, {4, 0}, Region::TipThumb}, {2, {10, 0}, Region::TipIndex},
      {3, {0, 10}, Region::Palm},    {4, {4, 10}, Region::Palm},    {5, {0, 14}, Region::Palm},
      {6, {4, 14}, Region::Palm},    {7, {20, 20}, Region::Other}};
  return HandTemplate::from_parts("small", s, {{-1, -1}, {21, -1}, {21, 21}, {-1, 21}}, true);
}

TaxelSequence seq(const std::vector<std::vector<double>>& rows, int64_t first_frame = 0) {
  TaxelSequence s;
  s.num_taxels = int(rows[0].size());
  for (size_t t = 0; t < rows.size(); ++t) s.add_row(first_frame + int64_t(t), rows[t].data());
  return s;
}

// Frame 0: GT 0.5 on taxel 0; prediction 0.25 on taxels 0 and 1, 0.01 on taxel 7.
// Frame 1: GT empty; prediction 0.03 on taxel 2 (just above τ).
// Frame 2: GT = prediction = 0.5 on palm taxels 3 and 4.
const std::vector<std::vector<double>> kGt = {
    {0.5, 0, 0, 0, 0, 0, 0, 0}, {0, 0, 0, 0, 0, 0, 0, 0}, {0, 0, 0, 0.5, 0.5, 0, 0, 0}};
const std::vector<std::vector<double>> kPred = {
    {0.25, 0.25, 0, 0, 0, 0, 0, 0.01}, {0, 0, 0.03, 0, 0, 0, 0, 0}, {0, 0, 0, 0.5, 0.5, 0, 0, 0}};

void expect_hand_values(const PressureMetrics& m) {
  EXPECT_EQ(m.frames, 3);
  EXPECT_NEAR(m.temporal_accuracy_pct, 200.0 / 3.0, 1e-12);          // frames 0 and 2 agree on "any contact"
  EXPECT_NEAR(m.contact_iou_pct, 60.0, 1e-12);                       // (1 + 0 + 2) / (2 + 1 + 2)
  EXPECT_NEAR(m.volumetric_iou_pct, 100.0 * 1.25 / 1.79, 1e-12);     // (0.25 + 0 + 1) / (0.76 + 0.03 + 1)
  EXPECT_NEAR(m.mae_newton, (102.0 + 6.0 + 0.0) / 24.0, 1e-12);       // 200·(0.25+0.25+0.01), 200·0.03, 0
  // CoP: tip_thumb (frame 0): GT at the origin, prediction at (4·0.25/(0.5+ε), 0); tip_index (frame 1, valid by
  // the prediction only): distance of 10·0.03/(0.03+ε) from the origin; palm (frame 2): 0. Other parts: no frame.
  const double thumb = 1.0 / (0.5 + 1e-6), index = 0.3 / (0.03 + 1e-6);
  EXPECT_NEAR(m.cop_error_by_part[0], thumb, 1e-12);
  EXPECT_NEAR(m.cop_error_by_part[1], index, 1e-12);
  EXPECT_NEAR(m.cop_error_by_part[5], 0.0, 1e-12);
  EXPECT_TRUE(std::isnan(m.cop_error_by_part[2]));
  EXPECT_EQ(m.cop_valid_frames[0], 1);
  EXPECT_EQ(m.cop_valid_frames[1], 1);
  EXPECT_EQ(m.cop_valid_frames[2], 0);
  EXPECT_EQ(m.cop_valid_frames[5], 1);
  EXPECT_NEAR(m.cop_error_grid, (thumb + index + 0.0) / 3.0, 1e-12);  // empty parts left out of the mean
}

TEST(Metrics, HandComputedExample) {
  const HandTemplate t = small_hand();
  expect_hand_values(compute_metrics(t, seq(kGt), seq(kPred)));
}

TEST(Metrics, SplitOfTwoClipsPoolsSums) {
  const HandTemplate t = small_hand();
  MetricAccumulator a(t), b(t), pooled(t);
  a.add(seq({kGt[0], kGt[1]}), seq({kPred[0], kPred[1]}));
  b.add(seq({kGt[2]}, 7), seq({kPred[2]}, 7));
  pooled.merge(a);
  pooled.merge(b);
  expect_hand_values(pooled.result());
  // Pooling is not the mean of the clips' scores: C-IoU per clip is 1/3 and 1, their mean 66.7 % != 60 %.
  EXPECT_NEAR(a.result().contact_iou_pct, 100.0 / 3.0, 1e-12);
  EXPECT_NEAR(b.result().contact_iou_pct, 100.0, 1e-12);
}

TEST(Metrics, IdenticalSequencesArePerfect) {
  const HandTemplate t = small_hand();
  const auto m = compute_metrics(t, seq(kGt), seq(kGt));
  EXPECT_EQ(m.volumetric_iou_pct, 100.0);
  EXPECT_EQ(m.contact_iou_pct, 100.0);
  EXPECT_EQ(m.temporal_accuracy_pct, 100.0);
  EXPECT_EQ(m.mae_newton, 0.0);
  EXPECT_EQ(m.cop_error_grid, 0.0);
}

TEST(Metrics, UndefinedIsNaN) {
  const HandTemplate t = small_hand();
  const std::vector<std::vector<double>> zeros = {std::vector<double>(8, 0.0)};
  const auto m = compute_metrics(t, seq(zeros), seq(zeros));
  EXPECT_EQ(m.temporal_accuracy_pct, 100.0);
  EXPECT_TRUE(std::isnan(m.contact_iou_pct));
  EXPECT_TRUE(std::isnan(m.volumetric_iou_pct));
  EXPECT_EQ(m.mae_newton, 0.0);
  EXPECT_TRUE(std::isnan(m.cop_error_grid));
  const auto e = MetricAccumulator(t).result();
  EXPECT_EQ(e.frames, 0);
  EXPECT_TRUE(std::isnan(e.temporal_accuracy_pct));
  EXPECT_TRUE(std::isnan(e.mae_newton));
}

TEST(Metrics, VolumetricIouIsScaleInvariantAndContactIsStrict) {
  const HandTemplate t = small_hand();
  auto scaled = [](std::vector<std::vector<double>> r, double k) {
    for (auto& row : r)
      for (double& v : row) v *= k;
    return r;
  };
  EXPECT_NEAR(compute_metrics(t, seq(scaled(kGt, 200)), seq(scaled(kPred, 200))).volumetric_iou_pct,
              100.0 * 1.25 / 1.79, 1e-12);
  // A prediction of exactly τ is not a contact.
  std::vector<std::vector<double>> gt = {std::vector<double>(8, 0.0)}, pred = gt;
  pred[0][2] = 0.025;
  const auto m = compute_metrics(t, seq(gt), seq(pred));
  EXPECT_EQ(m.temporal_accuracy_pct, 100.0);
  EXPECT_TRUE(std::isnan(m.contact_iou_pct));
}

TEST(CenterOfPressure, SingleLoadedTaxelIsItsCoordinate) {
  const HandTemplate t = small_hand();
  for (int m : {3, 4, 5, 6}) {
    std::vector<double> p(8, 0.0);
    p[m] = 1.0;
    const Point2 g = center_of_pressure(t, 5, p.data());
    EXPECT_DOUBLE_EQ(g.x, t.sensors()[m].grid.x / (1.0 + 1e-6));
    EXPECT_DOUBLE_EQ(g.y, t.sensors()[m].grid.y / (1.0 + 1e-6));
  }
  std::vector<double> p = {0, 0, 0, 0.2, 0.2, 0.2, 0.2, 0};  // uniform palm -> its centroid (2, 12)
  const Point2 c = center_of_pressure(t, 5, p.data());
  // A weighted mean of four terms: a few units in the last place (compilers may contract it into FMAs, as
  // AArch64 GCC does by default).
  EXPECT_NEAR(c.x, 2.0 * 0.8 / (0.8 + 1e-6), 8 * 2.0 * 2.2e-16);
  EXPECT_NEAR(c.y, 12.0 * 0.8 / (0.8 + 1e-6), 8 * 12.0 * 2.2e-16);
  EXPECT_EQ(contact_ratio(t, 5, p.data()), 1.0);
  p[3] = p[4] = p[5] = 0;
  EXPECT_EQ(contact_ratio(t, 5, p.data()), 0.25);  // 1 of 4 > 0.2: valid
}

TEST(Metrics, PartValidityThreshold) {
  // A part is valid only if more than 20 % of its taxels are in contact: 1 of 5 taxels (exactly 20 %) is not.
  std::vector<Sensor> s;
  for (int i = 0; i < 5; ++i) s.push_back({i, {double(i), 0}, Region::Palm});
  const HandTemplate t = HandTemplate::from_parts("five", s, {{-1, -1}, {5, -1}, {5, 1}}, true);
  TaxelSequence gt = seq({{0.5, 0, 0, 0, 0}}), pred = seq({{0, 0, 0, 0, 0.5}});
  EXPECT_EQ(compute_metrics(t, gt, pred).cop_valid_frames[5], 0);
  gt = seq({{0.5, 0.5, 0, 0, 0}});
  const auto m = compute_metrics(t, gt, pred);
  EXPECT_EQ(m.cop_valid_frames[5], 1);
  EXPECT_NEAR(m.cop_error_grid, std::abs(4.0 * 0.5 / (0.5 + 1e-6) - 0.5 / (1.0 + 1e-6)), 1e-12);
}

TEST(Metrics, MismatchedInputsAreErrors) {
  const HandTemplate t = small_hand();
  MetricAccumulator acc(t);
  EXPECT_THROW(acc.add(seq(kGt), seq(kPred, 1)), Error);
  EXPECT_THROW(acc.add(seq({{0.0, 0.0}}), seq({{0.0, 0.0}})), Error);
}

}  // namespace
}  // namespace egopd
