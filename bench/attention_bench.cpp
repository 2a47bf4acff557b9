// Attention, GEGLU, GroupNorm+SiLU and LayerNorm at the SVD U-Net's shapes (16 frames, 32x32 latent).
// Counters: GFLOP/s for attention (4*lq*lk*dh per head), GB/s (bytes read + written once) for the rest.
// The last argument selects the path: 1 = AVX2, 0 = portable; compare ratios within one run.
// The machine is shared, so each rate is reported twice: per wall-clock second ("GFLOP/s", "GB/s") and per
// second of process CPU time summed over threads ("GFLOP/s/core", "GB/s/core"), which load from others disturbs less.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/kernels/attention.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/norm.h"
#include "core/threading.h"

namespace {

constexpr double kPeakGflops = 196.0;  // this machine's FMA peak (2 cores)

std::vector<float> random_vector(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> ud(-1.0f, 1.0f);
  std::vector<float> v(n);
  for (float& x : v) x = ud(rng);
  return v;
}

// Runs fn once per iteration; sets `name` (per wall second) and `name/core` (per process-CPU second) to amount/time.
template <class Fn>
void run_measured(benchmark::State& state, const char* name, double amount, Fn fn) {
  double wall = 0.0;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    fn();
    wall += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const double iters = static_cast<double>(state.iterations());
  state.counters[name] = benchmark::Counter(amount * iters / wall);
  state.counters[std::string(name) + "/core"] = benchmark::Counter(amount, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["threads"] = egopd::num_threads();
}

void set_path(benchmark::State& state, int arg_index) {
  egopd::set_force_portable(state.range(arg_index) == 0);
  state.SetLabel(state.range(arg_index) ? "avx2" : "portable");
}

// Self-attention on a fused [batch, tokens, 3*C] qkv buffer (as the U-Net's attention blocks produce it).
// Args: batch, tokens, heads, dh, path.
void BM_SelfAttention(benchmark::State& state) {
  const int64_t batch = state.range(0), tokens = state.range(1), heads = state.range(2), dh = state.range(3);
  set_path(state, 4);
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
  run_measured(state, "GFLOP/s", gflop, [&] {
    egopd::attention(a);
    benchmark::DoNotOptimize(out.data());
  });
  state.counters["%peak"] = 100.0 * state.counters["GFLOP/s"] / kPeakGflops;
  egopd::set_force_portable(false);
}
BENCHMARK(BM_SelfAttention)
    ->ArgNames({"batch", "tokens", "heads", "dh", "avx2"})
    ->Args({16, 1024, 5, 64, 1})   // spatial, 32x32 latent
    ->Args({2, 1024, 5, 64, 0})    // portable reference (fewer frames: it is slow)
    ->Args({16, 256, 10, 64, 1})   // 16x16
    ->Args({16, 64, 20, 64, 1})    // 8x8
    ->Args({16, 16, 20, 64, 1})    // 4x4
    ->Args({1024, 16, 5, 64, 1})   // temporal: 1024 sequences of 16 frames
    ->Args({1024, 16, 5, 64, 0})
    ->Args({1, 257, 16, 80, 1})    // CLIP ViT-H
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
  egopd::set_force_portable(false);
}
BENCHMARK(BM_Geglu)->ArgNames({"rows", "d", "avx2"})->Args({16384, 1280, 1})->Args({16384, 1280, 0})
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

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
  egopd::set_force_portable(false);
}
BENCHMARK(BM_GroupNormSilu)
    ->ArgNames({"batch", "frames", "c", "s", "groups", "avx2"})
    ->Args({16, 1, 320, 1024, 32, 1})  // per-frame (spatial ResnetBlock2D)
    ->Args({1, 16, 320, 1024, 32, 1})  // video (temporal ResBlock)
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
  egopd::set_force_portable(false);
}
BENCHMARK(BM_LayerNorm)->ArgNames({"rows", "c", "avx2"})->Args({16384, 320, 1})->Args({16384, 320, 0})
    ->Unit(benchmark::kMillisecond)->MeasureProcessCPUTime();

}  // namespace

int main(int argc, char** argv) {
  egopd::set_num_threads(0);  // EGOPD_THREADS or all physical cores
  benchmark::AddCustomContext("peak_gflops", std::to_string(kPeakGflops));
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
