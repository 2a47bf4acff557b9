#pragma once
// Kernel profile: the time and arithmetic of every call of the kernel entry points (gemm, conv2d, conv_temporal3,
// attention), summed per kind and shape, so a benchmark can say which layer shapes run below the machine's peak.
// Off by default; when off a call costs one relaxed atomic load. Only the outermost kernel call of a thread is
// counted (a convolution's own GEMMs are part of the convolution).
#include <atomic>
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

namespace egopd {

struct KernelProfileEntry {
  std::string kernel;  // kind and shape, e.g. "gemm 2048x2560x320 B^T f16"
  int64_t calls = 0;
  double seconds = 0;
  double flop = 0;  // multiply-adds x 2 of the direct float32 algorithm (whatever algorithm ran)
};

void set_kernel_profiling(bool on);
bool kernel_profiling();
// The entries so far, slowest first; and forget them.
std::vector<KernelProfileEntry> kernel_profile();
void clear_kernel_profile();

namespace kernel_profile_detail {
extern std::atomic<bool> enabled;
void record(const std::string& kernel, double seconds, double flop);
}  // namespace kernel_profile_detail

// Times the enclosing kernel call when profiling is on: `describe` (called only then) names its kind and shape.
class KernelTimer {
 public:
  template <class Describe>
  KernelTimer(double flop, Describe describe) {
    if (!kernel_profile_detail::enabled.load(std::memory_order_relaxed) || depth_++ > 0) return;
    active_ = true;
    flop_ = flop;
    kernel_ = describe();
    start_ = std::chrono::steady_clock::now();
  }
  ~KernelTimer() {
    if (!active_) return;
    depth_ = 0;
    kernel_profile_detail::record(
        kernel_, std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count(), flop_);
  }
  KernelTimer(const KernelTimer&) = delete;
  KernelTimer& operator=(const KernelTimer&) = delete;

 private:
  static thread_local int depth_;
  bool active_ = false;
  double flop_ = 0;
  std::string kernel_;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace egopd
