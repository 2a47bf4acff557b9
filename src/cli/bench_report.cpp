#include <algorithm>
#include <chrono>
#include <cstdio>
#include <vector>
#include <cstdlib>

#include "cli/commands.h"
#include "core/block_pool.h"
#include "core/cpu.h"
#include "core/json_text.h"
#include "core/kernels/conv.h"
#include "core/kernels/fma_peak.h"
#include "core/kernels/gemm.h"
#include "core/kernels/kernel_profile.h"
#include "core/memory.h"
#include "core/timing.h"
#include "egopd/version.h"

namespace egopd {

double peak_gflops(int threads, bool probe_again) {
  if (const char* e = std::getenv("EGOPD_PEAK_GFLOPS"); e && std::atof(e) > 0) return std::atof(e) * threads;
  return probe_again ? remeasure_peak_gflops(kernel_path(), threads) : measured_peak_gflops(kernel_path(), threads);
}

double median(std::vector<double> t) {
  std::sort(t.begin(), t.end());
  return t.size() % 2 ? t[t.size() / 2] : 0.5 * (t[t.size() / 2 - 1] + t[t.size() / 2]);
}

CallTimes median_call_times(int64_t repeat, bool warmup, const std::function<void()>& call) {
  if (warmup) call();
  std::vector<double> wall, cpu;
  for (int64_t r = 0; r < std::max<int64_t>(repeat, 1); ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_seconds();
    call();
    cpu.push_back(process_cpu_seconds() - c0);
    wall.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return {median(wall), median(cpu)};
}

void warm_up(const std::string& target, int64_t n, const std::function<void()>& call) {
  for (int64_t e = 0; e < n; ++e) {
    const auto t0 = std::chrono::steady_clock::now();
    call();
    std::fprintf(stderr, "bench %s: warm-up %lld/%lld %.2f s (not timed)\n", target.c_str(), (long long)(e + 1),
                 (long long)n, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
}

void kernel_profile_fields(const std::vector<KernelProfileEntry>& entries, int64_t runs, double run_seconds,
                           nlohmann::ordered_json& into) {
  const double per_run = 1.0 / double(std::max<int64_t>(runs, 1));
  nlohmann::ordered_json rows = nlohmann::ordered_json::array();
  double total = 0;
  for (const KernelProfileEntry& e : entries) {
    nlohmann::ordered_json row;
    row["kernel"] = e.kernel;
    row["calls"] = double(e.calls) * per_run;
    row["seconds"] = e.seconds * per_run;
    row["gflop"] = e.flop * per_run * 1e-9;
    row["gflops"] = e.seconds > 0 ? e.flop / e.seconds * 1e-9 : 0.0;
    row["share_of_run"] = run_seconds > 0 ? e.seconds * per_run / run_seconds : 0.0;
    rows.push_back(row);
    total += e.seconds * per_run;
  }
  into["kernel_profile_seconds"] = total;  // the rest of the run: norms, activations, re-layouts
  into["kernel_profile"] = rows;
}

void add_kernel_profile(BenchReport& r, int64_t runs) {
  kernel_profile_fields(kernel_profile(), runs, r.seconds, r.extra);
  set_kernel_profiling(false);
  clear_kernel_profile();
}

void print_bench_report(const BenchReport& r, bool json) {
  const double gflops = r.seconds > 0 ? r.gflop / r.seconds : 0;
  nlohmann::ordered_json j;
  j["target"] = r.target;
  j["seconds"] = r.seconds;
  if (r.cpu_seconds > 0) j["cpu_seconds"] = r.cpu_seconds;
  j["gflop"] = r.gflop;
  j["gflops"] = gflops;
  const double peak = peak_gflops(r.threads, /*probe_again=*/true);  // the better of the probes before and after
  j["percent_of_peak"] = 100.0 * gflops / peak;
  j["peak_gflops"] = peak;
  // GFLOP are the multiply-adds of the direct float32 algorithm: with Winograd or reduced precision, less or cheaper
  // arithmetic runs, and GFLOP/s is a speed, not the share of the float32 peak in use.
  if (conv_algo() != ConvAlgo::Direct || precision() != Precision::Fp32)
    j["percent_of_peak_is"] = "direct-fp32-equivalent (--conv direct --precision fp32 for the share of the peak)";
  j["threads"] = r.threads;
  j["cpu"] = cpu_info().description();
  j["kernels"] = kernel_path_name(kernel_path());
  j["conv"] = conv_algo_name(conv_algo());
  j["kernel_features"] = kernel_path_features(kernel_path());
  j["precision"] = precision_name(precision());
  if (precision() == Precision::Bf16) j["bf16"] = bf16_native() ? "native (vdpbf16ps)" : "emulated";
  if (precision() == Precision::Int8) j["int8"] = int8_kernel();
  j["peak_rss_bytes"] = peak_rss_bytes();
  j["block_cache_mb"] = block_cache_limit() >> 20;  // at the end of the run (--low-mem sets 0)
  j["version"] = EGOPD_VERSION;
  for (auto it = r.extra.begin(); it != r.extra.end(); ++it) j[it.key()] = it.value();
  if (json) {
    std::printf("%s\n", dump_json(j).c_str());
  } else {
    std::printf("%s\n", dump_json(j, 2).c_str());
  }
}

}  // namespace egopd
