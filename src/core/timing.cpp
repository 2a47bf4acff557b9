#include "core/timing.h"

#include <algorithm>
#include <ctime>

#include "core/memory.h"

namespace egopd {

void StageTimes::add(const std::string& stage, double seconds) {
  for (auto& e : entries_)
    if (e.first == stage) {
      e.second += seconds;
      return;
    }
  entries_.push_back({stage, seconds});
}

void StageTimes::begin_memory_stage() {
  peak_before_ = std::max(peak_before_, peak_rss_bytes());
  reset_peak_rss();
}

void StageTimes::end_memory_stage(const std::string& stage) {
  const uint64_t peak = peak_rss_bytes();
  peak_before_ = std::max(peak_before_, peak);
  for (auto& e : peaks_)
    if (e.first == stage) {
      e.second = std::max(e.second, peak);
      return;
    }
  peaks_.push_back({stage, peak});
}

uint64_t StageTimes::peak_rss() const { return std::max(peak_before_, peak_rss_bytes()); }

double StageTimes::total() const {
  double t = 0;
  for (const auto& e : entries_) t += e.second;
  return t;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double process_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

}  // namespace egopd
