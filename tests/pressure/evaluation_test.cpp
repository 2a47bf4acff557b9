// The evaluation behind `egopd evaluate`: GT conversion, prediction conversion, file/directory matching, pooling.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "pressure/evaluation.h"
#include "pressure/normalization.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;

const std::string kShipped = std::string(EGOPD_TEST_DATA) + "/../data/templates/synthetic_right_hand.json";

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(::testing::TempDir()) / ("egopd_eval_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void write_text(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }

std::string error_of(const std::string& pred, const std::string& gt, const HandTemplate& t) {
  try {
    evaluate_taxel_files(pred, gt, t);
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

// Same small hand as metrics_test: 0,1 tip_thumb; 2 tip_index; 3-6 palm; 7 other.
HandTemplate small_hand() {
  const std::vector<Sensor> s = {
      {0, {0, 0}, Region::TipThumb}, {1, {4, 0}, Region::TipThumb}, {2, {10, 0}, Region::TipIndex},
      {3, {0, 10}, Region::Palm},    {4, {4, 10}, Region::Palm},    {5, {0, 14}, Region::Palm},
      {6, {4, 14}, Region::Palm},    {7, {20, 20}, Region::Other}};
  return HandTemplate::from_parts("small", s, {{-1, -1}, {21, -1}, {21, 21}, {-1, 21}}, true);
}
const char* kHeader8 = "frame,p0,p1,p2,p3,p4,p5,p6,p7\n";

TEST(Evaluation, GroundTruthIsStabilisedThenNormalised) {
  const HandTemplate t = HandTemplate::load(kShipped);
  TaxelSequence raw;
  raw.num_taxels = 162;
  std::vector<double> row(162, 0.0);
  const auto& g = t.segment_groups()[1];
  row[g[0]] = 30;                          // index group mean 5 N -> τ for all six
  for (int m : t.segment_groups()[2]) row[m] = 4;  // middle: 4 N each -> 0
  row[t.cop_parts()[5][0]] = 300;          // palm: clipped at p_max
  row[t.cop_parts()[5][1]] = 4.9;          // below p_min
  raw.add_row(0, row.data());
  const TaxelSequence gt = ground_truth_from_newtons(t, raw);
  for (int m : g) EXPECT_EQ(gt.row(0)[m], 0.025);
  for (int m : t.segment_groups()[2]) EXPECT_EQ(gt.row(0)[m], 0.0);
  EXPECT_EQ(gt.row(0)[t.cop_parts()[5][0]], 1.0);
  EXPECT_EQ(gt.row(0)[t.cop_parts()[5][1]], 0.0);
}

TEST(Evaluation, PredictionsAreScaledOnly) {
  const HandTemplate t = HandTemplate::load(kShipped);
  TaxelSequence pred;
  pred.num_taxels = 162;
  std::vector<double> row(162, 0.0);
  const auto& g = t.segment_groups()[0];
  row[g[0]] = 300;  // no clipping
  row[g[1]] = 3;    // no threshold
  pred.add_row(0, row.data());
  const TaxelSequence p = predictions_from_newtons(t, pred, false);
  EXPECT_EQ(p.row(0)[g[0]], 1.5);
  EXPECT_EQ(p.row(0)[g[1]], 0.015);
  const TaxelSequence s = predictions_from_newtons(t, pred, true);  // the stabilize_predictions option
  for (int m : g) EXPECT_NEAR(s.row(0)[m], 303.0 / 6.0 / 200.0, 1e-15);
}

TEST(Evaluation, NewtonsFromNormalized) {
  const TaxelSequence s = newtons_from_normalized({{0.5, 0.0, 1.25}, {0.025, 0.1, 0.0}}, 4);
  EXPECT_EQ(s.num_taxels, 3);
  EXPECT_EQ(s.frames, (std::vector<int64_t>{4, 5}));
  EXPECT_EQ(s.values, (std::vector<double>{100, 0, 250, 5, 20, 0}));
  EXPECT_THROW(newtons_from_normalized({{0.5}, {0.1, 0.2}}), Error);
}

TEST(Evaluation, PredictionEqualToStabilisedGroundTruthIsPerfect) {
  const HandTemplate t = HandTemplate::load(kShipped);
  // Readings 0 or within [5, 200] N, uniform within each finger-segment group (already stabilised).
  const double levels[] = {0, 5, 12.5, 100, 200, 0, 37.25};
  std::string csv = "frame";
  for (int m = 0; m < 162; ++m) csv += ",p" + std::to_string(m);
  csv += "\n";
  for (int f = 0; f < 16; ++f) {
    std::vector<double> row(162);
    for (int m = 0; m < 162; ++m) row[m] = levels[(m * 3 + f) % 7];
    for (const auto& g : t.segment_groups())
      for (int m : g) row[m] = row[g[0]];
    csv += std::to_string(f);
    for (double v : row) csv.append(",").append(std::to_string(v));
    csv += "\n";
  }
  const fs::path d = fresh_dir("perfect");
  write_text(d / "gt.csv", csv);
  const EvaluationReport r = evaluate_taxel_files((d / "gt.csv").string(), (d / "gt.csv").string(), t);
  EXPECT_EQ(r.pooled.frames, 16);
  EXPECT_EQ(r.pooled.temporal_accuracy_pct, 100.0);
  EXPECT_EQ(r.pooled.contact_iou_pct, 100.0);
  EXPECT_EQ(r.pooled.volumetric_iou_pct, 100.0);
  EXPECT_EQ(r.pooled.mae_newton, 0.0);
  EXPECT_EQ(r.pooled.cop_error_grid, 0.0);
  const auto j = evaluation_json(r, t, {});
  for (const char* k : {"temporal_accuracy_pct", "contact_iou_pct", "volumetric_iou_pct", "mae_newton", "cop_error_grid", "frames"})
    EXPECT_TRUE(j.contains(k)) << k;
  EXPECT_EQ(j["frames"].get<int>(), 16);
  EXPECT_TRUE(j["template"]["synthetic"].get<bool>());
  fs::remove_all(d);
}

TEST(Evaluation, SplitDirectoriesArePooled) {
  const HandTemplate t = small_hand();
  const fs::path pd = fresh_dir("pred"), gd = fresh_dir("gt");
  // clip_a = frames 0 and 1 of metrics_test's example, clip_b = its frame 2 (values in Newtons; prediction rows
  // in a different order than the GT rows).
  write_text(gd / "clip_a.csv", std::string(kHeader8) + "0,100,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0\n");
  write_text(pd / "clip_a.csv", std::string(kHeader8) + "1,0,0,6,0,0,0,0,0\n0,50,50,0,0,0,0,0,2\n");
  write_text(gd / "clip_b.csv", std::string(kHeader8) + "5,0,0,0,100,100,0,0,0\n");
  write_text(pd / "clip_b.csv", std::string(kHeader8) + "5,0,0,0,100,100,0,0,0\n");
  write_text(pd / "notes.txt", "ignored");
  const EvaluationReport r = evaluate_taxel_files(pd.string(), gd.string(), t);
  ASSERT_EQ(r.clips.size(), 2u);
  EXPECT_EQ(r.clips[0].name, "clip_a.csv");
  EXPECT_EQ(r.clips[1].metrics.frames, 1);
  const PressureMetrics& m = r.pooled;
  EXPECT_EQ(m.frames, 3);
  EXPECT_NEAR(m.temporal_accuracy_pct, 200.0 / 3.0, 1e-12);
  EXPECT_NEAR(m.contact_iou_pct, 60.0, 1e-12);
  // The 2 N prediction on taxel 7 counts (0.01 normalised, no p_min threshold on predictions).
  EXPECT_NEAR(m.volumetric_iou_pct, 100.0 * 1.25 / 1.79, 1e-12);
  EXPECT_NEAR(m.mae_newton, 108.0 / 24.0, 1e-12);
  EXPECT_NEAR(m.cop_error_grid, (1.0 / (0.5 + 1e-6) + 0.3 / (0.03 + 1e-6)) / 3.0, 1e-12);
  const auto j = evaluation_json(r, t, {});
  EXPECT_EQ(j["frames"].get<int>(), 3);
  EXPECT_TRUE(j["clips"][1]["contact_iou_pct"].is_number());
  EXPECT_TRUE(j["cop_error_by_part"]["tip_middle"]["error_grid"].is_null());  // undefined -> null

  write_text(gd / "clip_c.csv", std::string(kHeader8));
  EXPECT_NE(error_of(pd.string(), gd.string(), t).find("clip_c.csv: no prediction file of that name"), std::string::npos);
  fs::remove(gd / "clip_c.csv");
  write_text(pd / "clip_d.csv", std::string(kHeader8));
  EXPECT_NE(error_of(pd.string(), gd.string(), t).find("clip_d.csv: no ground truth file of that name"), std::string::npos);
  fs::remove_all(pd);
  fs::remove_all(gd);
}

TEST(Evaluation, InputErrors) {
  const HandTemplate t = small_hand();
  const fs::path d = fresh_dir("errors");
  write_text(d / "gt.csv", std::string(kHeader8) + "0,100,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0\n");
  write_text(d / "short.csv", std::string(kHeader8) + "0,100,0,0,0,0,0,0,0\n");
  write_text(d / "extra.csv", std::string(kHeader8) + "0,1,0,0,0,0,0,0,0\n1,0,0,0,0,0,0,0,0\n2,0,0,0,0,0,0,0,0\n");
  write_text(d / "narrow.csv", "frame,p0,p1\n0,1,2\n");
  const std::string gt = (d / "gt.csv").string();
  EXPECT_EQ(error_of((d / "short.csv").string(), gt, t), (d / "short.csv").string() + ": no prediction for frame 1 of " + gt);
  EXPECT_EQ(error_of((d / "extra.csv").string(), gt, t), (d / "extra.csv").string() + ": frame 2 is not in " + gt);
  EXPECT_EQ(error_of((d / "narrow.csv").string(), gt, t),
            (d / "narrow.csv").string() + ": 2 taxel columns, but the hand template 'small' has 8 sensors");
  EXPECT_EQ(error_of((d / "missing.csv").string(), gt, t), (d / "missing.csv").string() + ": no such file or directory");
  EXPECT_EQ(error_of(d.string(), gt, t), "evaluate: --pred and --gt must both be files or both be directories");
  fs::remove_all(d);
}

}  // namespace
}  // namespace egopd
