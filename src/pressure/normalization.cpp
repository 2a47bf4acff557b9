#include "pressure/normalization.h"

#include <algorithm>
#include <cfenv>
#include <cmath>

#include "core/error.h"

namespace egopd {

double normalize_reading(double r) {
  if (r < kPressureMin) return 0.0;
  return std::min(r, kPressureMax) / kPressureMax;
}

void stabilize_row(const HandTemplate& t, double* row) {
  for (const auto& g : t.segment_groups()) {
    if (g.empty()) continue;
    // Mean written as first + mean of differences: mathematically (1/6)Σ r_j, but exact when the group is
    // already uniform, so stabilising a stabilised signal changes nothing (not even the last bit).
    const double first = row[g[0]];
    double d = 0;
    for (int j : g) d += row[j] - first;
    const double mean = first + d / double(g.size());
    for (int j : g) row[j] = mean;
  }
}

LogBins::LogBins(int k, double v_min, double v_max) {
  if (k < 1) throw Error("log bins: need at least one bin (K = " + std::to_string(k) + ")");
  if (!(v_min > -1.0) || !(v_max > v_min)) throw Error("log bins: need -1 < v_min < v_max");
  const double lo = std::log(v_min + 1.0), hi = std::log(v_max + 1.0);
  // nearbyint rounds half to even in the default rounding mode (the reference rounding).
  const int mode = std::fegetround();
  std::fesetround(FE_TONEAREST);
  for (int i = 0; i <= k; ++i) edges_.push_back(std::nearbyint(std::exp(lo + (double(i) / k) * (hi - lo)) - 1.0));
  std::fesetround(mode);
}

int LogBins::label(double v) const {
  const int k = num_bins();
  const int j = int(std::upper_bound(edges_.begin(), edges_.end(), v) - edges_.begin());  // first edge > v
  return std::clamp(j, 1, k);
}

double LogBins::centre(int y) const {
  if (y < 1 || y > num_bins()) throw Error("log bins: label " + std::to_string(y) + " out of range");
  return 0.5 * (edges_[y - 1] + edges_[y]);
}

}  // namespace egopd
