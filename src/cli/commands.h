#pragma once
// Every `egopd` command and `egopd bench` target is a function taking its parsed options; main.cpp dispatches.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "cli/args.h"
#include "core/dtype.h"
#include "core/kernels/kernel_profile.h"
#include "core/tensor.h"
#include "core/weights.h"

namespace egopd {

int cmd_forward(const Args& a);
int cmd_evaluate(const Args& a);
int cmd_tokenize(const Args& a);
int cmd_predict(const Args& a);
int cmd_counterfactual(const Args& a);
int cmd_batch(const Args& a);
int cmd_manifest(const Args& a);

// bench targets
int bench_gemm(const Args& a);
int bench_conv2d(const Args& a);
int bench_clip_image(const Args& a);
int bench_clip_text(const Args& a);
int bench_unet(const Args& a);
int bench_vae_encode(const Args& a);
int bench_vae_decode(const Args& a);
int bench_pipeline(const Args& a);
// f32 | f16 | bf16 -> DType (error naming the option otherwise)
DType parse_weight_dtype(const std::string& s, const std::string& option);
// Deterministic random weights for every parameter of `params` (from WeightMap::recorder()), mapped as `label`:
// the file bench-<bench>-<synthetic_weights_id>.safetensors in the cache folder (cache_root()), written once and
// reused; without a cache folder a temporary file, unlinked once mapped.
std::shared_ptr<const WeightMap> bench_synthetic_weights(const std::string& bench, const std::string& label,
                                                         const std::vector<std::pair<std::string, Shape>>& params,
                                                         DType dtype);

// The folder `name` in the benchmarks' cache folder (cache_root(), else <temp>/egopd-cache), built once and reused:
// fill(dir) writes it into a temporary folder that appears whole under `name` (AtomicDir; `marker`, a file every
// complete folder has, tells a finished one), or not at all on an error or interrupt. Temporaries a killed bench
// left there go after an hour untouched.
std::string cached_bench_folder(const std::string& name, const std::string& marker,
                                const std::function<void(const std::string& dir)>& fill);

// Shared reporting of every bench target: one JSON object (--json) or a short text block with at least
// seconds (median per call), gflops, percent_of_peak and peak_rss_bytes.
struct BenchReport {
  std::string target;
  double seconds = 0;      // median per call
  double cpu_seconds = 0;  // median process CPU time per call (all threads; 0: not measured)
  double gflop = 0;    // work per call
  int threads = 1;
  nlohmann::ordered_json extra = nlohmann::ordered_json::object();
};
void print_bench_report(const BenchReport& r, bool json);
// --kernel-profile: r.extra["kernel_profile"] from the kernel calls recorded so far (core/kernels/kernel_profile.h),
// per run of `runs`, slowest first, with their GFLOP/s and share of the run; then profiling stops.
void add_kernel_profile(BenchReport& r, int64_t runs);
// The same fields from `entries` into `into`: "kernel_profile_seconds" (the sum) and "kernel_profile" (the rows), per
// run of `runs` of `run_seconds` each.
void kernel_profile_fields(const std::vector<KernelProfileEntry>& entries, int64_t runs, double run_seconds,
                           nlohmann::ordered_json& into);
double median(std::vector<double> values);  // of one or more values; an even count: the mean of the middle two
// Median wall and process-CPU seconds of `repeat` calls, after one untimed warm-up call when `warmup` (first
// touches of mapped weights and scratch buffers).
struct CallTimes {
  double wall = 0, cpu = 0;
};
CallTimes median_call_times(int64_t repeat, bool warmup, const std::function<void()>& call);
// `n` untimed calls (bench unet, vae_*: --warmup), each reported on stderr as
// "bench <target>: warm-up i/n S s (not timed)".
void warm_up(const std::string& target, int64_t n, const std::function<void()>& call);
// FP32 peak of `threads` threads on the kernel path in use, measured with an FMA loop (override:
// EGOPD_PEAK_GFLOPS per core); probe_again: probe once more and keep the better figure (fma_peak.h).
double peak_gflops(int threads, bool probe_again = false);

}  // namespace egopd
