#pragma once
// The machine's measured FP32 peak for a kernel path: every thread runs independent FMA chains on the path's
// widest registers (zmm for avx512, ymm for avx2, scalar for portable) at once, so the figure includes the all-core
// clock under vector load; each thread is timed by its own CPU time (robust to a shared machine). Used for the
// "% of peak" of every benchmark.
#include "core/cpu.h"

namespace egopd {

// GFLOP/s of `threads` threads together (measured once per path and thread count, then cached).
double measured_peak_gflops(KernelPath path, int threads);

}  // namespace egopd
