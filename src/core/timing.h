#pragma once
// Wall-clock accounting per named stage (bench breakdowns, pipeline timings). Recording is off unless a
// StageTimes is attached; ScopedStage on a null StageTimes costs nothing.
#include <chrono>
#include <cstdint>
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

  // Also record each stage's peak RSS: the kernel's high-water mark is restarted when a stage begins (Linux
  // /proc/self/clear_refs), so the process-wide VmHWM alone no longer tells the run's peak: use peak_rss().
  void track_memory(bool on) { track_memory_ = on; }
  bool tracking_memory() const { return track_memory_; }
  void begin_memory_stage();                                  // called by ScopedStage
  void end_memory_stage(const std::string& stage);            // called by ScopedStage
  const std::vector<std::pair<std::string, uint64_t>>& stage_peaks() const { return peaks_; }  // bytes, max per name
  uint64_t peak_rss() const;  // the whole process's peak so far, across the restarts

 private:
  std::vector<std::pair<std::string, double>> entries_;
  std::vector<std::pair<std::string, uint64_t>> peaks_;
  bool track_memory_ = false;
  uint64_t peak_before_ = 0;  // highest VmHWM seen before a restart
};

class ScopedStage {
 public:
  ScopedStage(StageTimes* times, const char* stage) : times_(times), stage_(stage) {
    if (!times_) return;
    if (times_->tracking_memory()) times_->begin_memory_stage();
    start_ = std::chrono::steady_clock::now();
  }
  ~ScopedStage() {
    if (!times_) return;
    times_->add(stage_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count());
    if (times_->tracking_memory()) times_->end_memory_stage(stage_);
  }
  ScopedStage(const ScopedStage&) = delete;
  ScopedStage& operator=(const ScopedStage&) = delete;

 private:
  StageTimes* times_;
  const char* stage_;
  std::chrono::steady_clock::time_point start_;
};

double seconds_since(std::chrono::steady_clock::time_point t0);
// CPU time this process has used so far (all threads): unlike wall time, it does not grow while other programs
// hold the cores, so one-thread benchmarks on a shared machine compare by it.
double process_cpu_seconds();

}  // namespace egopd
