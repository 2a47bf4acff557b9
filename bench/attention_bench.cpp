// Attention, GEGLU, GroupNorm+SiLU, LayerNorm and the token re-layouts at the SVD U-Net's shapes (16 frames, 32x32
// latent).
// Counters: GFLOP/s for attention (4*lq*lk*dh per head), GB/s (bytes read + written once) for the rest.
// The last argument selects the kernel path: 2 = AVX-512, 1 = AVX2, 0 = portable (paths the CPU lacks are
// skipped); compare ratios within one run. %peak is against the measured FMA peak of the path (fma_peak.h).
// The machine is shared, so each rate is reported twice: per wall-clock second ("GFLOP/s", "GB/s") and per
// second of process CPU time summed over threads ("GFLOP/s/core", "GB/s/core"), which load from others disturbs
// less (threads spinning at a barrier count as busy, so it errs low). %peak/core compares the per-core rate with
// the machine peak divided by its physical cores.
#include <benchmark/benchmark.h>

#include <time.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/kernels/attention.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/fma_peak.h"
#include "core/kernels/gemm.h"
#include "core/kernels/layout.h"
#include "core/kernels/norm.h"
#include "core/threading.h"

namespace {

std::vector<float> random_vector(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ud(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = ud(rng);
  return v;
}

double process_cpu_seconds() {
  timespec ts;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

// Runs fn once per iteration; sets `name` (amount per wall second) and `name/core` (amount per second of process
// CPU time, i.e. per busy core). Returns the per-core rate.
template <class Fn>
double run_measured(benchmark::State& state, const char* name, double amount, Fn fn) {
  double wall = 0.0, cpu = 0.0;
  for (auto _ : state) {
    const double c0 = process_cpu_seconds();
    const auto t0 = std::chrono::steady_clock::now();
    fn();
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cpu += process_cpu_seconds() - c0;
  }
  const double iters = static_cast<double>(state.iterations());
  state.counters[name] = benchmark::Counter(amount * iters / wall);
  state.counters[std::string(name) + "/core"] = benchmark::Counter(amount * iters / cpu);
  state.counters["threads"] = egopd::num_threads();
  return amount * iters / cpu;
}

// %peak (wall-clock rate) and %peak/core (CPU-time rate) against the measured peak of the path in use.
void set_peak_counters(benchmark::State& state, double per_core_gflops) {
  const int threads = egopd::num_threads();
  const double peak = egopd::measured_peak_gflops(egopd::kernel_path(), threads);
  state.counters["%peak"] = 100.0 * state.counters["GFLOP/s"] / peak;
  state.counters["%peak/core"] = 100.0 * per_core_gflops / (peak / threads);
}

void set_path(benchmark::State& state, int arg_index) {
  const auto path = egopd::KernelPath(state.range(arg_index));
  if (!egopd::kernel_path_supported(path)) return state.SkipWithError("kernel path not supported by this CPU");
  egopd::set_kernel_path(path);
  state.SetLabel(egopd::kernel_path_name(path));
}

// Self-attention on a fused [batch, tokens, 3*C] qkv buffer (as the U-Net's attention blocks produce it).
// Args: batch, tokens, heads, dh, path; computed in `precision` (the Bf16 variants: --precision bf16's rule).
void self_attention(benchmark::State& state, egopd::Precision precision) {
  const int64_t batch = state.range(0), tokens = state.range(1), heads = state.range(2), dh = state.range(3);
  set_path(state, 4);
  egopd::set_precision(precision);
  const int64_t C = heads * dh;
  const std::vector<float> qkv = random_vector(batch * tokens * 3 * C, 1);
  std::vector<float> out(batch * tokens * C);
  egopd::AttentionArgs a;
  a.batch = batch, a.heads = heads, a.lq = a.lk = tokens, a.dh = dh;
  a.q = qkv.data(), a.k = qkv.data() + C, a.v = qkv.data() + 2 * C;
  a.q_ld = a.k_ld = a.v_ld = 3 * C;
  a.q_bs = a.k_bs = a.v_bs = tokens * 3 * C;
  a.out = out.data(), a.out_ld = C, a.out_bs = tokens * C;
  a.scale = 1.0f / std::sqrt(static_cast<float>(dh));
  const double gflop = 4.0 * tokens * tokens * dh * heads * batch * 1e-9;
  const double per_core = run_measured(state, "GFLOP/s", gflop, [&] {
    egopd::attention(a);
    benchmark::DoNotOptimize(out.data());
  });
  set_peak_counters(state, per_core);
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
  egopd::set_precision(egopd::Precision::Fp32);
}
void BM_SelfAttention(benchmark::State& state) { self_attention(state, egopd::Precision::Fp32); }
void BM_SelfAttentionBf16(benchmark::State& state) { self_attention(state, egopd::Precision::Bf16); }
BENCHMARK(BM_SelfAttention)
    ->ArgNames({"batch", "tokens", "heads", "dh", "path"})
    ->Args({16, 1024, 5, 64, 1})   // spatial, 32x32 latent
    ->Args({16, 1024, 5, 64, 2})
    ->Args({2, 1024, 5, 64, 0})    // portable reference (fewer frames: it is slow)
    ->Args({16, 256, 10, 64, 1})   // 16x16
    ->Args({16, 256, 10, 64, 2})
    ->Args({16, 64, 20, 64, 1})    // 8x8
    ->Args({16, 64, 20, 64, 2})
    ->Args({16, 16, 20, 64, 1})    // 4x4
    ->Args({16, 16, 20, 64, 2})
    ->Args({1024, 16, 5, 64, 1})   // 1024 contiguous 16-row sequences (temporal layout: see below)
    ->Args({1024, 16, 5, 64, 2})
    ->Args({1, 257, 16, 80, 1})    // CLIP ViT-H
    ->Args({1, 257, 16, 80, 2})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

// Temporal self-attention as the U-Net runs it: q, k, v are frame-major [frames, tokens, C], one sequence per
// token (q_ld = tokens*C between frames, q_bs = C between sequences). Args: frames, tokens, heads, dh, path.
void temporal_attention(benchmark::State& state, egopd::Precision precision) {
  const int64_t frames = state.range(0), tokens = state.range(1), heads = state.range(2), dh = state.range(3);
  set_path(state, 4);
  egopd::set_precision(precision);
  const int64_t C = heads * dh, n = frames * tokens * C;
  const std::vector<float> q = random_vector(n, 11), k = random_vector(n, 12), v = random_vector(n, 13);
  std::vector<float> out(n);
  egopd::AttentionArgs a;
  a.batch = tokens, a.heads = heads, a.lq = a.lk = frames, a.dh = dh;
  a.q = q.data(), a.k = k.data(), a.v = v.data(), a.out = out.data();
  a.q_ld = a.k_ld = a.v_ld = a.out_ld = tokens * C;
  a.q_bs = a.k_bs = a.v_bs = a.out_bs = C;
  a.scale = 1.0f / std::sqrt(static_cast<float>(dh));
  const double gflop = 4.0 * frames * frames * dh * heads * tokens * 1e-9;
  const double per_core = run_measured(state, "GFLOP/s", gflop, [&] {
    egopd::attention(a);
    benchmark::DoNotOptimize(out.data());
  });
  set_peak_counters(state, per_core);
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
  egopd::set_precision(egopd::Precision::Fp32);
}
void BM_TemporalAttention(benchmark::State& state) { temporal_attention(state, egopd::Precision::Fp32); }
void BM_TemporalAttentionBf16(benchmark::State& state) { temporal_attention(state, egopd::Precision::Bf16); }
BENCHMARK(BM_TemporalAttention)
    ->ArgNames({"frames", "tokens", "heads", "dh", "path"})
    ->Args({16, 1024, 5, 64, 1})
    ->Args({16, 1024, 5, 64, 2})
    ->Args({16, 1024, 5, 64, 0})
    ->Args({16, 256, 10, 64, 1})
    ->Args({16, 256, 10, 64, 2})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

// --precision bf16 (attention.h): vdpbf16ps on AVX512-BF16, the float32 kernels on rounded copies elsewhere.
BENCHMARK(BM_SelfAttentionBf16)
    ->ArgNames({"batch", "tokens", "heads", "dh", "path"})
    ->Args({16, 1024, 5, 64, 1})
    ->Args({16, 1024, 5, 64, 2})
    ->Args({1024, 16, 5, 64, 2})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();
BENCHMARK(BM_TemporalAttentionBf16)
    ->ArgNames({"frames", "tokens", "heads", "dh", "path"})
    ->Args({16, 1024, 5, 64, 1})
    ->Args({16, 1024, 5, 64, 2})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

// Args: rows, d (p is [rows, 2d]), path.
void BM_Geglu(benchmark::State& state) {
  const int64_t rows = state.range(0), d = state.range(1);
  set_path(state, 2);
  const std::vector<float> p = random_vector(rows * 2 * d, 2);
  std::vector<float> out(rows * d);
  run_measured(state, "GB/s", 3.0 * rows * d * sizeof(float) * 1e-9, [&] {
    egopd::geglu(p.data(), rows, d, out.data());
    benchmark::DoNotOptimize(out.data());
  });
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
}
BENCHMARK(BM_Geglu)
    ->ArgNames({"rows", "d", "path"})
    ->Args({16384, 1280, 1})  // U-Net FF at 32x32 (p is [16384, 2560])
    ->Args({16384, 1280, 2})
    ->Args({16384, 1280, 0})
    ->Args({128, 1280, 1})    // cache-resident: compute cost of GELU alone
    ->Args({128, 1280, 2})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

// Args: batch, frames, c, s, groups, path (GroupNorm + fused SiLU, in place).
void BM_GroupNormSilu(benchmark::State& state) {
  const int64_t batch = state.range(0), frames = state.range(1), c = state.range(2), s = state.range(3),
                groups = state.range(4);
  set_path(state, 5);
  const int64_t n = batch * frames * c * s;
  const std::vector<float> x = random_vector(n, 3), gamma = random_vector(c, 4), beta = random_vector(c, 5);
  std::vector<float> y(n);
  run_measured(state, "GB/s", 2.0 * n * sizeof(float) * 1e-9, [&] {
    egopd::group_norm(x.data(), y.data(), batch, frames, c, s, groups, gamma.data(), beta.data(), 1e-5f, true);
    benchmark::DoNotOptimize(y.data());
  });
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
}
BENCHMARK(BM_GroupNormSilu)
    ->ArgNames({"batch", "frames", "c", "s", "groups", "path"})
    ->Args({16, 1, 320, 1024, 32, 1})  // per-frame (spatial ResnetBlock2D)
    ->Args({16, 1, 320, 1024, 32, 2})
    ->Args({1, 16, 320, 1024, 32, 1})  // video (temporal ResBlock)
    ->Args({1, 16, 320, 1024, 32, 2})
    ->Args({1, 16, 320, 1024, 32, 0})
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

// Args: rows, c, path.
void BM_LayerNorm(benchmark::State& state) {
  const int64_t rows = state.range(0), c = state.range(1);
  set_path(state, 2);
  const std::vector<float> x = random_vector(rows * c, 6), gamma = random_vector(c, 7), beta = random_vector(c, 8);
  std::vector<float> y(rows * c);
  run_measured(state, "GB/s", 2.0 * rows * c * sizeof(float) * 1e-9, [&] {
    egopd::layer_norm(x.data(), y.data(), rows, c, gamma.data(), beta.data(), 1e-5f);
    benchmark::DoNotOptimize(y.data());
  });
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
}
BENCHMARK(BM_LayerNorm)->ArgNames({"rows", "c", "path"})->Args({16384, 320, 2})->Args({16384, 320, 1})->Args({16384, 320, 0})
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

// Args: batch, rows, cols, add, path: [batch, rows, cols] -> [batch, cols, rows] (add: onto a residual).
void BM_Transpose(benchmark::State& state) {
  const int64_t batch = state.range(0), rows = state.range(1), cols = state.range(2);
  const bool add = state.range(3) != 0;
  set_path(state, 4);
  const int64_t n = batch * rows * cols;
  const std::vector<float> x = random_vector(n, 9);
  std::vector<float> y = random_vector(n, 10);
  run_measured(state, "GB/s", (add ? 3.0 : 2.0) * n * sizeof(float) * 1e-9, [&] {
    if (add) egopd::transpose_add_batched(x.data(), y.data(), batch, rows, cols);
    else egopd::transpose_batched(x.data(), y.data(), batch, rows, cols);
    benchmark::DoNotOptimize(y.data());
  });
  egopd::set_kernel_path(egopd::supported_kernel_paths().back());
}
BENCHMARK(BM_Transpose)
    ->ArgNames({"batch", "rows", "cols", "add", "path"})
    ->ArgsProduct({{16}, {320}, {1024}, {0}, {0, 1, 2}})  // Tok: [F, C, HW] -> [F, HW, C]
    ->ArgsProduct({{16}, {1024}, {320}, {1}, {0, 1, 2}})  // Tok^-1 onto the residual
    ->Unit(benchmark::kMillisecond)
    ->MeasureProcessCPUTime();

}  // namespace

int main(int argc, char** argv) {
  egopd::set_num_threads(0);  // EGOPD_THREADS or all physical cores
  for (egopd::KernelPath path : egopd::supported_kernel_paths())
    benchmark::AddCustomContext(std::string("peak_gflops_") + egopd::kernel_path_name(path),
                                std::to_string(egopd::measured_peak_gflops(path, egopd::num_threads())));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
