#include "core/kernels/elementwise.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/simd_namespace.h"

namespace egopd {

// The SIMD kernels of this architecture: avx2/elementwise.cpp on x86-64 (avx2 and avx512 paths), neon/elementwise.cpp
// on AArch64; serial kernels on contiguous spans.
namespace EGOPD_SIMD_NS {
void silu_inplace(float* x, int64_t n);
void gelu_inplace(float* x, int64_t n);
void quick_gelu_inplace(float* x, int64_t n);
void erf_inplace(float* x, int64_t n);
void geglu_row(const float* a, const float* g, int64_t d, float* out);
void blend_inplace(float* y, const float* x, float a, int64_t n);
void add_inplace(float* y, const float* x, int64_t n);
}  // namespace EGOPD_SIMD_NS
namespace simd = EGOPD_SIMD_NS;
#undef EGOPD_SIMD_NS

namespace {

constexpr int64_t kParallelMin = 1 << 15;  // below this many elements threads cost more than they save
bool run_parallel(int64_t n) { return n >= kParallelMin && !omp_in_parallel(); }

// Calls fn(begin, end) on contiguous chunks of [0, n) (64-float aligned), in parallel when n is large.
template <class Fn>
void for_chunks(int64_t n, Fn fn) {
  if (!run_parallel(n)) {
    fn(int64_t{0}, n);
    return;
  }
#pragma omp parallel
  {
    const int64_t nt = omp_get_num_threads(), t = omp_get_thread_num();
    const int64_t per = ((n + nt - 1) / nt + 63) / 64 * 64;
    const int64_t b = std::min(n, t * per), e = std::min(n, b + per);
    if (b < e) fn(b, e);
  }
}

float sigmoid_mul(float x, float k) { return x / (1.0f + std::exp(-k * x)); }

// 0.5 x (1 + erf(x/sqrt2)); for x < 0 the bracket is erfc(|x|/sqrt2), evaluated without cancellation.
float gelu_scalar(float x) {
  const float z = x * 0.70710678118654752f;
  return 0.5f * x * (z < 0.0f ? std::erfc(-z) : 1.0f + std::erf(z));
}

}  // namespace

void silu_inplace(float* x, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::silu_inplace(x + b, e - b); });
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x[i] = sigmoid_mul(x[i], 1.0f);
  });
}

void gelu_inplace(float* x, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::gelu_inplace(x + b, e - b); });
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x[i] = gelu_scalar(x[i]);
  });
}

void quick_gelu_inplace(float* x, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::quick_gelu_inplace(x + b, e - b); });
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x[i] = sigmoid_mul(x[i], 1.702f);
  });
}

void erf_inplace(float* x, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::erf_inplace(x + b, e - b); });
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) x[i] = std::erf(x[i]);
  });
}

void geglu(const float* p, int64_t rows, int64_t d, float* out) {
  const bool vec = use_simd();
#pragma omp parallel for schedule(static) if (run_parallel(rows * d))
  for (int64_t r = 0; r < rows; ++r) {
    const float* a = p + r * 2 * d;  // [rows, 2d]: value half, then gate half
    const float* g = a + d;
    float* o = out + r * d;
    if (vec) {
      simd::geglu_row(a, g, d, o);
    } else {
      for (int64_t i = 0; i < d; ++i) o[i] = a[i] * gelu_scalar(g[i]);
    }
  }
}

void upsample_nearest2x(const float* x, int64_t planes, int64_t h, int64_t w, float* y) {
#pragma omp parallel for schedule(static) if (run_parallel(planes * h * w * 4))
  for (int64_t p = 0; p < planes; ++p) {
    const float* xp = x + p * h * w;
    float* yp = y + p * 4 * h * w;
    for (int64_t i = 0; i < h; ++i) {
      float* row0 = yp + (2 * i) * (2 * w);
      for (int64_t j = 0; j < w; ++j) row0[2 * j] = row0[2 * j + 1] = xp[i * w + j];
      std::copy_n(row0, 2 * w, row0 + 2 * w);  // output row 2i+1 repeats row 2i
    }
  }
}

void timestep_embedding(const float* t, int64_t n, int64_t dim, float* out) {
  if (dim % 2 != 0) throw Error("timestep_embedding: dim must be even, got " + std::to_string(dim));
  const int64_t half = dim / 2;
  const float neg_log_period = static_cast<float>(-std::log(10000.0));  // the double constant rounded to float32
  for (int64_t r = 0; r < n; ++r) {
    const float tr = t[r];
    float* o = out + r * dim;
    for (int64_t i = 0; i < half; ++i) {
      const float e = neg_log_period * static_cast<float>(i) / static_cast<float>(half);
      const float arg = tr * std::exp(e);
      o[i] = std::cos(arg);
      o[half + i] = std::sin(arg);
    }
  }
}

void blend_inplace(float* y, const float* x, float a, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::blend_inplace(y + b, x + b, a, e - b); });
  const float c = 1.0f - a;
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) y[i] = a * x[i] + c * y[i];
  });
}

void add_inplace(float* y, const float* x, int64_t n) {
  if (use_simd()) return for_chunks(n, [&](int64_t b, int64_t e) { simd::add_inplace(y + b, x + b, e - b); });
  for_chunks(n, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) y[i] += x[i];
  });
}

}  // namespace egopd
