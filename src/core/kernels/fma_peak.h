#pragma once
// The machine's measured FP32 peak for a kernel path: every thread runs independent FMA chains on the path's
// widest registers (zmm for avx512, ymm for avx2, scalar for portable) at once, so the figure includes the all-core
// clock under vector load; each thread is timed by its own CPU time (robust to a shared machine). Used for the
// "% of peak" of every benchmark.
#include "core/cpu.h"

namespace egopd {

// GFLOP/s of `threads` threads together: the best probe so far for this path and thread count (probed on first
// use). A probe is the best of its rounds over at least 0.2 s.
double measured_peak_gflops(KernelPath path, int threads);
// Probes again and keeps the better figure, which it returns: on a shared host a moment of contention lowers one
// probe, so a benchmark probes before and after its run.
double remeasure_peak_gflops(KernelPath path, int threads);

}  // namespace egopd
