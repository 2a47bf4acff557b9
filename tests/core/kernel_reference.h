#pragma once
// Double-precision references shared by the kernel tests.
#include <cmath>
#include <string>

#include "core/cpu.h"
#include "core/kernels/gemm.h"

namespace egopd::test {

constexpr double kU = 1.0 / 16777216.0;  // 2^-24: float32 unit roundoff

inline double act_ref(Act act, double x) {
  switch (act) {
    case Act::None: return x;
    case Act::SiLU: return x / (1.0 + std::exp(-x));
    case Act::GELU: return 0.5 * x * (1.0 + std::erf(x / std::sqrt(2.0)));
    case Act::QuickGELU: return x / (1.0 + std::exp(-1.702 * x));
  }
  return x;
}

// Runs the kernels of path p while in scope, then the path that was in use before.
struct KernelPathGuard {
  KernelPath before = kernel_path();
  explicit KernelPathGuard(KernelPath p) { set_kernel_path(p); }
  ~KernelPathGuard() { set_kernel_path(before); }
};

// Every kernel path, for parameterised suites (paths the CPU lacks are skipped with a message).
inline const KernelPath kAllKernelPaths[] = {KernelPath::Portable, KernelPath::Avx2, KernelPath::Avx512,
                                            KernelPath::Neon};

}  // namespace egopd::test
