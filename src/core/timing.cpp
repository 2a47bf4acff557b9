#include "core/timing.h"

namespace egopd {

void StageTimes::add(const std::string& stage, double seconds) {
  for (auto& e : entries_)
    if (e.first == stage) {
      e.second += seconds;
      return;
    }
  entries_.push_back({stage, seconds});
}

double StageTimes::total() const {
  double t = 0;
  for (const auto& e : entries_) t += e.second;
  return t;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace egopd
