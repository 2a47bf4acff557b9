#pragma once
// Pressure units (pressure.md §1-§3): raw glove Newtons -> normalised p in {0} ∪ [τ, 1], finger-segment
// stabilisation, and the log-space bins of the sequence baselines. All double precision.
#include <vector>

#include "pressure/hand_template.h"

namespace egopd {

constexpr double kPressureMin = 5.0;                       // p_min, N: glove noise floor
constexpr double kPressureMax = 200.0;                     // p_max, N: normalisation scale
constexpr double kContactTau = kPressureMin / kPressureMax;  // τ = 0.025; contact iff p > τ (strict)

// §1: 0 below p_min, else min(r, p_max)/p_max.
double normalize_reading(double newtons);
inline bool in_contact(double p) { return p > kContactTau; }

// §2: replaces every taxel of each group G_k by the group mean (row of M values, in place). For raw readings this
// runs before normalize_reading; for predictions it may run on normalised values (same result, no threshold).
void stabilize_row(const HandTemplate& t, double* row);

// §3: K log-spaced bins over [v_min, v_max] (Newtons), edges rounded half-to-even.
class LogBins {
 public:
  LogBins(int k, double v_min, double v_max);
  int num_bins() const { return int(edges_.size()) - 1; }
  const std::vector<double>& edges() const { return edges_; }  // b_0 .. b_K
  // Label y in 1..K with b_{y-1} <= v < b_y; v >= b_K -> K; v < b_0 -> 1 (clipped into the first bin).
  int label(double v) const;
  double centre(int label) const;  // (b_{y-1} + b_y) / 2, the "bin expectation" value

 private:
  std::vector<double> edges_;
};

}  // namespace egopd
