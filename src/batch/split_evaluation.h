#pragma once
// `egopd evaluate --manifest`: the paper's metrics of a batch run's outputs per split (pressure.md §8, sums pooled
// over every frame of every clip of the split), the main-table layout (one row per run, five columns per split),
// per-clip rows, and the clips that are missing or failed, named, never silently left out.
//
// Frames: prediction frame f of a clip is frame source_index[f] of the clip (summary.json); its ground truth is
// that frame's: the row with that frame number in a taxel CSV (raw glove readings in N; rows of unsampled frames
// are not used), or that pressure heatmap, read out to taxels with the same template and operator as the
// predictions (egopressurediff §7 steps 2-7 on H_raw = grey value / max, squashed to the predictions' S x S) and
// then taken as glove readings. Either way the ground truth is then stabilised and normalised (§1-§2).
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "batch/manifest.h"
#include "pressure/evaluation.h"

namespace egopd {

struct ClipResult {
  enum class Status { kEvaluated, kMissing, kFailed, kNoGroundTruth };
  std::string id;
  std::vector<std::string> splits;
  Status status = Status::kMissing;
  std::string detail;  // failed: its error line; evaluated: "taxel CSV" or "heatmaps"
  PressureMetrics metrics;
};

struct SplitResult {
  std::string name;  // a manifest split, or "all" (every clip)
  int64_t clips = 0, evaluated = 0;
  std::vector<std::string> missing, failed, no_ground_truth;
  PressureMetrics pooled;
};

struct ManifestEvaluation {
  std::string run;  // row label of the main table
  std::vector<ClipResult> clips;   // manifest order
  std::vector<SplitResult> splits;  // manifest splits in order of appearance, then "all"
  bool complete() const;           // no clip missing or failed
};

ManifestEvaluation evaluate_manifest(const Manifest& m, const std::string& pred_dir, const std::string& run,
                                     const HandTemplate& t, const EvaluationOptions& opt = {});

nlohmann::ordered_json manifest_evaluation_json(const ManifestEvaluation& e, const HandTemplate& t,
                                                const EvaluationOptions& opt);
std::string manifest_evaluation_markdown(const ManifestEvaluation& e, const HandTemplate& t);
// Per-clip rows: id,splits,status,frames,temporal_accuracy_pct,contact_iou_pct,volumetric_iou_pct,mae_newton,
// cop_error_grid,detail (undefined metrics empty).
std::string manifest_evaluation_csv(const ManifestEvaluation& e);

}  // namespace egopd
