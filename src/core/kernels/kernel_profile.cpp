#include "core/kernels/kernel_profile.h"

#include <algorithm>
#include <map>
#include <mutex>

namespace egopd {

namespace kernel_profile_detail {
std::atomic<bool> enabled{false};

namespace {
std::mutex mutex;
std::map<std::string, KernelProfileEntry>& table() {
  static std::map<std::string, KernelProfileEntry> t;
  return t;
}
}  // namespace

void record(const std::string& kernel, double seconds, double flop) {
  std::lock_guard<std::mutex> lock(mutex);
  KernelProfileEntry& e = table()[kernel];
  e.kernel = kernel;
  e.calls += 1;
  e.seconds += seconds;
  e.flop += flop;
}
}  // namespace kernel_profile_detail

thread_local int KernelTimer::depth_ = 0;

void set_kernel_profiling(bool on) { kernel_profile_detail::enabled.store(on, std::memory_order_relaxed); }
bool kernel_profiling() { return kernel_profile_detail::enabled.load(std::memory_order_relaxed); }

std::vector<KernelProfileEntry> kernel_profile() {
  std::lock_guard<std::mutex> lock(kernel_profile_detail::mutex);
  std::vector<KernelProfileEntry> out;
  for (const auto& [key, e] : kernel_profile_detail::table()) out.push_back(e);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.seconds > b.seconds; });
  return out;
}

void clear_kernel_profile() {
  std::lock_guard<std::mutex> lock(kernel_profile_detail::mutex);
  kernel_profile_detail::table().clear();
}

}  // namespace egopd
