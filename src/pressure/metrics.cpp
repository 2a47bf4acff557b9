#include "pressure/metrics.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/error.h"
#include "pressure/normalization.h"

namespace egopd {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

double ratio_or_nan(double num, double den) { return den == 0 ? kNaN : num / den; }

}  // namespace

Point2 center_of_pressure(const HandTemplate& t, int part, const double* p) {
  double sx = 0, sy = 0, s = 0;
  for (int m : t.cop_parts()[part]) {
    const Point2 g = t.sensors()[m].grid;
    sx += p[m] * g.x;
    sy += p[m] * g.y;
    s += p[m];
  }
  return {sx / (s + kCopEps), sy / (s + kCopEps)};
}

double contact_ratio(const HandTemplate& t, int part, const double* p) {
  const auto& ids = t.cop_parts()[part];
  if (ids.empty()) return 0;
  int n = 0;
  for (int m : ids) n += in_contact(p[m]);
  return double(n) / double(ids.size());
}

MetricAccumulator::MetricAccumulator(const HandTemplate& t) : t_(&t) {}

void MetricAccumulator::add_frame(const double* gt, const double* pred) {
  const int M = t_->num_sensors();
  bool any_gt = false, any_pred = false;
  for (int m = 0; m < M; ++m) {
    const bool c = in_contact(gt[m]), ch = in_contact(pred[m]);
    any_gt = any_gt || c;
    any_pred = any_pred || ch;
    contact_inter_ += c && ch;
    contact_union_ += c || ch;
    vol_min_ += std::min(gt[m], pred[m]);
    vol_max_ += std::max(gt[m], pred[m]);
    abs_err_ += kPressureMax * std::abs(pred[m] - gt[m]);
  }
  any_contact_agree_ += any_gt == any_pred;
  for (int r = 0; r < kNumCopParts; ++r) {
    if (!(contact_ratio(*t_, r, gt) > kCopValidRatio || contact_ratio(*t_, r, pred) > kCopValidRatio)) continue;
    const Point2 a = center_of_pressure(*t_, r, pred), b = center_of_pressure(*t_, r, gt);
    cop_err_sum_[r] += std::hypot(a.x - b.x, a.y - b.y);
    ++cop_frames_[r];
  }
  ++frames_;
}

void MetricAccumulator::add(const TaxelSequence& gt, const TaxelSequence& pred) {
  const int M = t_->num_sensors();
  if (gt.num_taxels != M || pred.num_taxels != M)
    throw Error("metrics: sequences have " + std::to_string(gt.num_taxels) + " and " +
                std::to_string(pred.num_taxels) + " taxels, the template " + std::to_string(M));
  if (gt.frames != pred.frames) throw Error("metrics: ground truth and prediction cover different frames");
  for (int64_t t = 0; t < gt.num_frames(); ++t) add_frame(gt.row(t), pred.row(t));
}

void MetricAccumulator::merge(const MetricAccumulator& o) {
  EGOPD_CHECK(o.t_ == t_, "merging metrics of different templates");
  frames_ += o.frames_;
  any_contact_agree_ += o.any_contact_agree_;
  contact_inter_ += o.contact_inter_;
  contact_union_ += o.contact_union_;
  vol_min_ += o.vol_min_;
  vol_max_ += o.vol_max_;
  abs_err_ += o.abs_err_;
  for (int r = 0; r < kNumCopParts; ++r) {
    cop_err_sum_[r] += o.cop_err_sum_[r];
    cop_frames_[r] += o.cop_frames_[r];
  }
}

PressureMetrics MetricAccumulator::result() const {
  PressureMetrics m;
  m.frames = frames_;
  m.temporal_accuracy_pct = 100.0 * ratio_or_nan(double(any_contact_agree_), double(frames_));
  m.contact_iou_pct = 100.0 * ratio_or_nan(double(contact_inter_), double(contact_union_));
  m.volumetric_iou_pct = 100.0 * ratio_or_nan(vol_min_, vol_max_);
  m.mae_newton = ratio_or_nan(abs_err_, double(frames_) * t_->num_sensors());
  double sum = 0;
  int parts = 0;
  for (int r = 0; r < kNumCopParts; ++r) {
    m.cop_valid_frames[r] = cop_frames_[r];
    m.cop_error_by_part[r] = ratio_or_nan(cop_err_sum_[r], double(cop_frames_[r]));
    if (cop_frames_[r] > 0) sum += m.cop_error_by_part[r], ++parts;  // parts with no valid frame are left out
  }
  m.cop_error_grid = ratio_or_nan(sum, double(parts));
  return m;
}

PressureMetrics compute_metrics(const HandTemplate& t, const TaxelSequence& gt, const TaxelSequence& pred) {
  MetricAccumulator acc(t);
  acc.add(gt, pred);
  return acc.result();
}

}  // namespace egopd
