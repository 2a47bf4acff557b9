#include "core/kernels/fma_peak.h"

#include <omp.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <map>
#include <mutex>
#include <utility>

#if defined(__x86_64__)
#include <immintrin.h>
#elif defined(__aarch64__)
#include <arm_neon.h>
#endif

namespace egopd {

namespace {

constexpr int kChains = 12;  // independent accumulators: more than FMA latency x FMA pipes on current cores
// Each loop stores its result here: a side effect, so the compiler cannot treat a loop as a pure function and move
// it across the clock reads around it.
volatile float g_sink = 0;
inline float sink(float v) {
  g_sink = v;
  return v;
}

#if defined(__x86_64__)
__attribute__((target("avx512f"))) float fma_loop_avx512(int64_t iters) {
  __m512 acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = _mm512_set1_ps(float(i) * 1e-3f);
  const __m512 m = _mm512_set1_ps(0.9999f), c = _mm512_set1_ps(1e-4f);
  for (int64_t it = 0; it < iters; ++it) {
#pragma GCC unroll 12
    for (int i = 0; i < kChains; ++i) acc[i] = _mm512_fmadd_ps(acc[i], m, c);
  }
  __m512 s = acc[0];
  for (int i = 1; i < kChains; ++i) s = _mm512_add_ps(s, acc[i]);
  alignas(64) float v[16];  // (not _mm512_reduce_add_ps: GCC 12's header warns of an uninitialised operand in it)
  _mm512_store_ps(v, s);
  return sink(v[0] + v[15]);
}

__attribute__((target("avx2,fma"))) float fma_loop_avx2(int64_t iters) {
  __m256 acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = _mm256_set1_ps(float(i) * 1e-3f);
  const __m256 m = _mm256_set1_ps(0.9999f), c = _mm256_set1_ps(1e-4f);
  for (int64_t it = 0; it < iters; ++it) {
#pragma GCC unroll 12
    for (int i = 0; i < kChains; ++i) acc[i] = _mm256_fmadd_ps(acc[i], m, c);
  }
  __m256 s = acc[0];
  for (int i = 1; i < kChains; ++i) s = _mm256_add_ps(s, acc[i]);
  alignas(32) float v[8];
  _mm256_store_ps(v, s);
  return sink(v[0] + v[7]);
}
#endif

#if defined(__aarch64__)
float fma_loop_neon(int64_t iters) {
  float32x4_t acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = vdupq_n_f32(float(i) * 1e-3f);
  const float32x4_t m = vdupq_n_f32(0.9999f), c = vdupq_n_f32(1e-4f);
  for (int64_t it = 0; it < iters; ++it) {
#pragma GCC unroll 12
    for (int i = 0; i < kChains; ++i) acc[i] = vfmaq_f32(c, acc[i], m);
  }
  float32x4_t s = acc[0];
  for (int i = 1; i < kChains; ++i) s = vaddq_f32(s, acc[i]);
  return sink(vaddvq_f32(s));
}
#endif

float fma_loop_scalar(int64_t iters) {
  float acc[kChains];
  for (int i = 0; i < kChains; ++i) acc[i] = float(i) * 1e-3f;
  for (int64_t it = 0; it < iters; ++it)
    for (int i = 0; i < kChains; ++i) acc[i] = acc[i] * 0.9999f + 1e-4f;  // what portable code compiles to
  float s = 0;
  for (int i = 0; i < kChains; ++i) s += acc[i];
  return sink(s);
}

int lanes(KernelPath p) {
  return p == KernelPath::Avx512 ? 16 : p == KernelPath::Avx2 ? 8 : p == KernelPath::Neon ? 4 : 1;
}

float run(KernelPath p, int64_t iters) {
#if defined(__x86_64__)
  if (p == KernelPath::Avx512) return fma_loop_avx512(iters);
  if (p == KernelPath::Avx2) return fma_loop_avx2(iters);
#elif defined(__aarch64__)
  if (p == KernelPath::Neon) return fma_loop_neon(iters);
#endif
  return fma_loop_scalar(iters);
}

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return double(ts.tv_sec) + 1e-9 * double(ts.tv_nsec);
}

// Each thread times its own loop in thread CPU time, so time slices taken by other programs on a shared machine
// do not lower the figure; the threads still run at once (the all-core clock). Best of the rounds run in 0.2 s (at
// least three): a slower moment of the host shorter than that leaves some rounds at full speed.
double measure(KernelPath p, int threads) {
#if defined(EGOPD_EMULATE_AVX512)
  if (p == KernelPath::Avx512) p = KernelPath::Avx2;  // emulated (kernels/avx512/isa.h) on AVX2 hardware
#endif
  const int64_t iters = p == KernelPath::Portable ? 2'000'000 : 4'000'000;  // ~0.02-0.05 s at 3 GHz
  double best = 0;
  run(p, iters / 4);  // wake the vector units (and the clock) up
  const auto start = std::chrono::steady_clock::now();
  const auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  for (int round = 0; round < 3 || (elapsed() < 0.2 && round < 40); ++round) {
    double total = 0;
#pragma omp parallel num_threads(threads) reduction(+ : total)
    {
      const double c0 = thread_cpu_seconds();
      run(p, iters);
      total += 2.0 * kChains * lanes(p) * double(iters) / (thread_cpu_seconds() - c0) * 1e-9;
    }
    best = std::max(best, total);
  }
  return best;
}

// The best probe per (path, threads); probe: measure again even if one is kept.
double best_peak(KernelPath path, int threads, bool probe) {
  static std::mutex mu;
  static std::map<std::pair<int, int>, double> best;
  std::lock_guard<std::mutex> lock(mu);
  double& b = best[std::make_pair(int(path), threads)];
  if (b == 0 || probe) b = std::max(b, measure(path, threads));
  return b;
}
}  // namespace

double measured_peak_gflops(KernelPath path, int threads) { return best_peak(path, threads, false); }
double remeasure_peak_gflops(KernelPath path, int threads) { return best_peak(path, threads, true); }

}  // namespace egopd
