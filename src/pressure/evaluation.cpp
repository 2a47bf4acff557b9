#include "pressure/evaluation.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "core/error.h"
#include "pressure/normalization.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;

void check_width(const HandTemplate& t, const TaxelSequence& s, const std::string& path) {
  if (s.num_taxels != t.num_sensors())
    throw Error(path + ": " + std::to_string(s.num_taxels) + " taxel columns, but the hand template '" + t.name() +
                "' has " + std::to_string(t.num_sensors()) + " sensors");
}

// Prediction rows reordered to the GT's frame order; every frame must appear on both sides.
TaxelSequence align_to(const TaxelSequence& gt, const TaxelSequence& pred, const std::string& gt_path,
                       const std::string& pred_path) {
  std::unordered_map<int64_t, int64_t> where;
  for (int64_t t = 0; t < pred.num_frames(); ++t) where[pred.frames[t]] = t;
  TaxelSequence out;
  out.num_taxels = pred.num_taxels;
  for (int64_t t = 0; t < gt.num_frames(); ++t) {
    const auto it = where.find(gt.frames[t]);
    if (it == where.end())
      throw Error(pred_path + ": no prediction for frame " + std::to_string(gt.frames[t]) + " of " + gt_path);
    out.add_row(gt.frames[t], pred.row(it->second));
  }
  if (pred.num_frames() != gt.num_frames()) {
    std::unordered_map<int64_t, bool> in_gt;
    for (int64_t f : gt.frames) in_gt[f] = true;
    for (int64_t f : pred.frames)
      if (!in_gt.count(f)) throw Error(pred_path + ": frame " + std::to_string(f) + " is not in " + gt_path);
  }
  return out;
}

PressureMetrics evaluate_clip(const std::string& pred_path, const std::string& gt_path, const HandTemplate& t,
                              const EvaluationOptions& opt, MetricAccumulator& pooled) {
  const TaxelSequence gt_raw = read_taxel_csv(gt_path);
  check_width(t, gt_raw, gt_path);
  const TaxelSequence pred_raw = read_taxel_csv(pred_path);
  check_width(t, pred_raw, pred_path);
  const TaxelSequence gt = ground_truth_from_newtons(t, gt_raw);
  const TaxelSequence pred = align_to(gt, predictions_from_newtons(t, pred_raw, opt.stabilize_predictions),
                                     gt_path, pred_path);
  MetricAccumulator clip(t);
  clip.add(gt, pred);
  pooled.merge(clip);
  return clip.result();
}

std::vector<std::string> csv_names(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".csv") names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace

nlohmann::ordered_json number_or_null(double v) { return std::isfinite(v) ? nlohmann::ordered_json(v) : nullptr; }

void put_metrics_json(nlohmann::ordered_json& j, const PressureMetrics& m) {
  j["temporal_accuracy_pct"] = number_or_null(m.temporal_accuracy_pct);
  j["contact_iou_pct"] = number_or_null(m.contact_iou_pct);
  j["volumetric_iou_pct"] = number_or_null(m.volumetric_iou_pct);
  j["mae_newton"] = number_or_null(m.mae_newton);
  j["cop_error_grid"] = number_or_null(m.cop_error_grid);
  j["frames"] = m.frames;
}

TaxelSequence ground_truth_from_newtons(const HandTemplate& t, const TaxelSequence& raw) {
  TaxelSequence s = raw;
  for (int64_t f = 0; f < s.num_frames(); ++f) {
    double* r = s.row(f);
    stabilize_row(t, r);  // before normalisation: the p_min threshold applies to the group mean
    for (int m = 0; m < s.num_taxels; ++m) r[m] = normalize_reading(r[m]);
  }
  return s;
}

TaxelSequence predictions_from_newtons(const HandTemplate& t, const TaxelSequence& pred, bool stabilize) {
  TaxelSequence s = pred;
  for (double& v : s.values) v /= kPressureMax;
  if (stabilize)
    for (int64_t f = 0; f < s.num_frames(); ++f) stabilize_row(t, s.row(f));
  return s;
}

TaxelSequence newtons_from_normalized(const std::vector<std::vector<double>>& p, int64_t first_frame) {
  TaxelSequence s;
  s.num_taxels = p.empty() ? 0 : int(p[0].size());
  std::vector<double> row(s.num_taxels);
  for (size_t t = 0; t < p.size(); ++t) {
    if (int(p[t].size()) != s.num_taxels) throw Error("taxel frames of different lengths");
    for (int m = 0; m < s.num_taxels; ++m) row[m] = kPressureMax * p[t][m];
    s.add_row(first_frame + int64_t(t), row.data());
  }
  return s;
}

EvaluationReport evaluate_taxel_files(const std::string& pred, const std::string& gt, const HandTemplate& t,
                                      const EvaluationOptions& opt) {
  for (const auto& p : {pred, gt})
    if (!fs::exists(p)) throw Error(p + ": no such file or directory");
  const bool pred_dir = fs::is_directory(pred), gt_dir = fs::is_directory(gt);
  if (pred_dir != gt_dir) throw Error("evaluate: --pred and --gt must both be files or both be directories");
  EvaluationReport rep;
  MetricAccumulator pooled(t);
  if (!pred_dir) {
    rep.clips.push_back({pred, evaluate_clip(pred, gt, t, opt, pooled)});
    rep.pooled = pooled.result();
    return rep;
  }
  const auto pred_names = csv_names(pred), gt_names = csv_names(gt);
  if (gt_names.empty()) throw Error(gt + ": no .csv files in directory");
  for (const auto& n : pred_names)
    if (!std::binary_search(gt_names.begin(), gt_names.end(), n))
      throw Error((fs::path(pred) / n).string() + ": no ground truth file of that name in " + gt);
  for (const auto& n : gt_names) {
    if (!std::binary_search(pred_names.begin(), pred_names.end(), n))
      throw Error((fs::path(gt) / n).string() + ": no prediction file of that name in " + pred);
    rep.clips.push_back({n, evaluate_clip((fs::path(pred) / n).string(), (fs::path(gt) / n).string(), t, opt, pooled)});
  }
  rep.pooled = pooled.result();
  return rep;
}

nlohmann::ordered_json evaluation_json(const EvaluationReport& r, const HandTemplate& t, const EvaluationOptions& opt) {
  nlohmann::ordered_json j;
  put_metrics_json(j, r.pooled);
  nlohmann::ordered_json parts = nlohmann::ordered_json::object();
  for (int p = 0; p < kNumCopParts; ++p)
    parts[region_name(Region(p))] = {{"error_grid", number_or_null(r.pooled.cop_error_by_part[p])},
                                     {"valid_frames", r.pooled.cop_valid_frames[p]}};
  j["cop_error_by_part"] = parts;
  j["clips"] = nlohmann::ordered_json::array();
  for (const auto& c : r.clips) {
    nlohmann::ordered_json cj;
    cj["name"] = c.name;
    put_metrics_json(cj, c.metrics);
    j["clips"].push_back(cj);
  }
  j["template"] = {{"name", t.name()}, {"file", t.source()}, {"synthetic", t.synthetic()}};
  j["stabilize_predictions"] = opt.stabilize_predictions;
  return j;
}

}  // namespace egopd
