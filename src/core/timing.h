#pragma once
// Wall-clock accounting per named stage (bench breakdowns, pipeline timings). Recording is off unless a
// StageTimes is attached; ScopedStage on a null StageTimes costs nothing.
#include <chrono>
#include <string>
#include <utility>
#include <vector>

namespace egopd {

class StageTimes {
 public:
  void add(const std::string& stage, double seconds);
  const std::vector<std::pair<std::string, double>>& entries() const { return entries_; }  // first-seen order
  double total() const;
  void clear() { entries_.clear(); }

 private:
  std::vector<std::pair<std::string, double>> entries_;
};

class ScopedStage {
 public:
  ScopedStage(StageTimes* times, const char* stage) : times_(times), stage_(stage) {
    if (times_) start_ = std::chrono::steady_clock::now();
  }
  ~ScopedStage() {
    if (times_)
      times_->add(stage_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
  }
  ScopedStage(const ScopedStage&) = delete;
  ScopedStage& operator=(const ScopedStage&) = delete;

 private:
  StageTimes* times_;
  const char* stage_;
  std::chrono::steady_clock::time_point start_;
};

double seconds_since(std::chrono::steady_clock::time_point t0);

}  // namespace egopd
