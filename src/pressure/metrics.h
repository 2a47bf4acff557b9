#pragma once
// Evaluation metrics (pressure.md §8), PressureVision-style pooling: every sum runs over all frames of all clips
// of a split, so a split's score is computed from pooled sums, never as a mean of per-clip scores.
// Inputs are normalised pressures: GT stabilised + normalised, predictions p̂ (no threshold, no clipping).
#include <array>
#include <cstdint>

#include "pressure/hand_template.h"
#include "pressure/taxel_csv.h"

namespace egopd {

constexpr double kCopEps = 1e-6;         // ε of the CoP denominator
constexpr double kCopValidRatio = 0.2;   // a part is valid in a frame if > 20% of its taxels are in contact

// Centre of pressure of part r: Σ p·g / (Σ p + ε) over the part's taxels, in grid units.
Point2 center_of_pressure(const HandTemplate& t, int part, const double* p);
// Fraction of the part's taxels with p > τ (0 for an empty part).
double contact_ratio(const HandTemplate& t, int part, const double* p);

struct PressureMetrics {
  int64_t frames = 0;
  // NaN where the spec's denominator is zero ("undefined").
  double temporal_accuracy_pct = 0, contact_iou_pct = 0, volumetric_iou_pct = 0, mae_newton = 0,
         cop_error_grid = 0;
  std::array<double, kNumCopParts> cop_error_by_part{};      // NaN for a part with no valid frame
  std::array<int64_t, kNumCopParts> cop_valid_frames{};      // |T_r|
};

class MetricAccumulator {
 public:
  explicit MetricAccumulator(const HandTemplate& t);
  // One frame: M normalised GT values and M normalised predictions.
  void add_frame(const double* gt, const double* pred);
  // Every frame of two sequences with the same frames (checked) and M taxels.
  void add(const TaxelSequence& gt, const TaxelSequence& pred);
  void merge(const MetricAccumulator& other);  // pooling of clips
  PressureMetrics result() const;

 private:
  const HandTemplate* t_;
  int64_t frames_ = 0, any_contact_agree_ = 0;
  int64_t contact_inter_ = 0, contact_union_ = 0;
  double vol_min_ = 0, vol_max_ = 0, abs_err_ = 0;
  std::array<double, kNumCopParts> cop_err_sum_{};
  std::array<int64_t, kNumCopParts> cop_frames_{};
};

// Convenience: metrics of one pair of sequences.
PressureMetrics compute_metrics(const HandTemplate& t, const TaxelSequence& gt, const TaxelSequence& pred);

}  // namespace egopd
