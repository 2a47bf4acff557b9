#pragma once
// Split evaluation behind `egopd evaluate`: taxel CSVs (Newtons) of one clip or of a directory of clips are
// converted to the metric domain and pooled (pressure.md §8).
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "pressure/hand_template.h"
#include "pressure/metrics.h"
#include "pressure/taxel_csv.h"

namespace egopd {

// Raw glove readings (N) -> the paper's ground truth: stabilised (§2) on the raw values, then normalised (§1).
TaxelSequence ground_truth_from_newtons(const HandTemplate& t, const TaxelSequence& raw);
// Predicted Newtons -> p̂ = P̂ / p_max, no threshold and no clipping (§7); optionally stabilised
// (the spec's `stabilize_predictions`, off by default).
TaxelSequence predictions_from_newtons(const HandTemplate& t, const TaxelSequence& pred, bool stabilize);

// Read-out results (normalised p̂ per frame, e.g. PressureRenderer::Frame::p) -> Newtons for the taxel CSV,
// frames numbered first_frame, first_frame + 1, ...
TaxelSequence newtons_from_normalized(const std::vector<std::vector<double>>& p, int64_t first_frame = 0);

struct EvaluationOptions {
  bool stabilize_predictions = false;
};

struct ClipEvaluation {
  std::string name;  // file name (directory mode) or the prediction path (single clip)
  PressureMetrics metrics;
};

struct EvaluationReport {
  std::vector<ClipEvaluation> clips;
  PressureMetrics pooled;  // from the sums over every frame of every clip
};

// `pred` and `gt` are both files (one clip) or both directories; in directory mode every *.csv is matched by
// file name and each side must have a partner. Within a clip, frames are matched by frame number (every GT frame
// needs a prediction and vice versa).
EvaluationReport evaluate_taxel_files(const std::string& pred, const std::string& gt, const HandTemplate& t,
                                      const EvaluationOptions& opt = {});

// A metric value for JSON: null when undefined (NaN).
nlohmann::ordered_json number_or_null(double v);
// temporal_accuracy_pct, contact_iou_pct, volumetric_iou_pct, mae_newton, cop_error_grid, frames into `j`.
void put_metrics_json(nlohmann::ordered_json& j, const PressureMetrics& m);

// The JSON written by `egopd evaluate --json`: temporal_accuracy_pct, contact_iou_pct, volumetric_iou_pct,
// mae_newton, cop_error_grid, frames (undefined metrics are null), then per-part CoP, per-clip results and the
// template (with its synthetic flag).
nlohmann::ordered_json evaluation_json(const EvaluationReport& r, const HandTemplate& t, const EvaluationOptions& opt);

}  // namespace egopd
