#include "core/kernels/elementwise.h"

#include <omp.h>

#include <cmath>
#include <string>

#include "core/error.h"

namespace egopd {

namespace {

constexpr int64_t kParallelMin = 1 << 15;  // below this many elements threads cost more than they save
bool run_parallel(int64_t n) { return n >= kParallelMin && !omp_in_parallel(); }

float gelu_scalar(float v) { return 0.5f * v * (1.0f + std::erf(v * 0.70710678118654752f)); }

}  // namespace

void silu_inplace(float* x, int64_t n) {
#pragma omp parallel for schedule(static) if (run_parallel(n))
  for (int64_t i = 0; i < n; ++i) x[i] = x[i] / (1.0f + std::exp(-x[i]));
}

void gelu_inplace(float* x, int64_t n) {
#pragma omp parallel for schedule(static) if (run_parallel(n))
  for (int64_t i = 0; i < n; ++i) x[i] = gelu_scalar(x[i]);
}

void quick_gelu_inplace(float* x, int64_t n) {
#pragma omp parallel for schedule(static) if (run_parallel(n))
  for (int64_t i = 0; i < n; ++i) x[i] = x[i] / (1.0f + std::exp(-1.702f * x[i]));
}

void geglu(const float* p, int64_t rows, int64_t d, float* out) {
#pragma omp parallel for schedule(static) if (run_parallel(rows * d))
  for (int64_t r = 0; r < rows; ++r) {
    const float* a = p + r * 2 * d;
    const float* g = a + d;
    float* o = out + r * d;
    for (int64_t i = 0; i < d; ++i) o[i] = a[i] * gelu_scalar(g[i]);
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
      float* row1 = row0 + 2 * w;
      for (int64_t j = 0; j < 2 * w; ++j) row1[j] = row0[j];
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
  const float b = 1.0f - a;
#pragma omp parallel for schedule(static) if (run_parallel(n))
  for (int64_t i = 0; i < n; ++i) y[i] = a * x[i] + b * y[i];
}

void add_inplace(float* y, const float* x, int64_t n) {
#pragma omp parallel for schedule(static) if (run_parallel(n))
  for (int64_t i = 0; i < n; ++i) y[i] += x[i];
}

}  // namespace egopd
