#include "core/kernels/norm.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace egopd {

namespace {

float silu_scalar(float v) { return v / (1.0f + std::exp(-v)); }

// Statistics of one (batch, group): frames x cg x s values; frame stride is c*s. Two passes in double.
void group_stats(const float* x, int64_t frames, int64_t frame_stride, int64_t count, float eps, float* mean_out,
                 float* rstd_out) {
  double sum = 0.0;
  for (int64_t f = 0; f < frames; ++f) {
    const float* p = x + f * frame_stride;
    for (int64_t i = 0; i < count; ++i) sum += p[i];
  }
  const double n = static_cast<double>(frames * count);
  const double mean = sum / n;
  double sq = 0.0;
  for (int64_t f = 0; f < frames; ++f) {
    const float* p = x + f * frame_stride;
    for (int64_t i = 0; i < count; ++i) {
      const double d = p[i] - mean;
      sq += d * d;
    }
  }
  *mean_out = static_cast<float>(mean);
  *rstd_out = static_cast<float>(1.0 / std::sqrt(sq / n + static_cast<double>(eps)));
}

}  // namespace

void group_norm(const float* x, float* y, int64_t batch, int64_t frames, int64_t c, int64_t s, int64_t groups,
                const float* gamma, const float* beta, float eps, bool silu) {
  const int64_t cg = c / groups;
  const int64_t units = batch * groups;
  const bool par = !omp_in_parallel() && units > 1 && batch * frames * c * s >= (1 << 15);
#pragma omp parallel for schedule(dynamic, 1) if (par)
  for (int64_t u = 0; u < units; ++u) {
    const int64_t b = u / groups, g = u % groups;
    const int64_t base = b * frames * c * s + g * cg * s;
    float mean, rstd;
    group_stats(x + base, frames, c * s, cg * s, eps, &mean, &rstd);
    for (int64_t f = 0; f < frames; ++f) {
      for (int64_t ci = 0; ci < cg; ++ci) {
        const int64_t ch = g * cg + ci;
        const float sc = rstd * (gamma ? gamma[ch] : 1.0f);
        const float sh = (beta ? beta[ch] : 0.0f) - mean * sc;
        const float* xp = x + base + f * c * s + ci * s;
        float* yp = y + base + f * c * s + ci * s;
        for (int64_t i = 0; i < s; ++i) {
          const float v = xp[i] * sc + sh;
          yp[i] = silu ? silu_scalar(v) : v;
        }
      }
    }
  }
}

void layer_norm(const float* x, float* y, int64_t rows, int64_t c, const float* gamma, const float* beta, float eps) {
  const bool par = !omp_in_parallel() && rows > 1 && rows * c >= (1 << 15);
#pragma omp parallel for schedule(static) if (par)
  for (int64_t r = 0; r < rows; ++r) {
    const float* xp = x + r * c;
    float* yp = y + r * c;
    double sum = 0.0;
    for (int64_t i = 0; i < c; ++i) sum += xp[i];
    const double mean = sum / static_cast<double>(c);
    double sq = 0.0;
    for (int64_t i = 0; i < c; ++i) {
      const double d = xp[i] - mean;
      sq += d * d;
    }
    const float rstd = static_cast<float>(1.0 / std::sqrt(sq / static_cast<double>(c) + static_cast<double>(eps)));
    const float m = static_cast<float>(mean);
    for (int64_t i = 0; i < c; ++i) {
      const float v = (xp[i] - m) * rstd;
      yp[i] = v * (gamma ? gamma[i] : 1.0f) + (beta ? beta[i] : 0.0f);
    }
  }
}

void softmax_rows(float* x, int64_t rows, int64_t cols) {
  const bool par = !omp_in_parallel() && rows > 1 && rows * cols >= (1 << 15);
#pragma omp parallel for schedule(static) if (par)
  for (int64_t r = 0; r < rows; ++r) {
    float* p = x + r * cols;
    float mx = -INFINITY;
    for (int64_t i = 0; i < cols; ++i) mx = std::max(mx, p[i]);
    double sum = 0.0;
    for (int64_t i = 0; i < cols; ++i) {
      p[i] = std::exp(p[i] - mx);
      sum += p[i];
    }
    const float inv = static_cast<float>(1.0 / sum);
    for (int64_t i = 0; i < cols; ++i) p[i] *= inv;
  }
}

}  // namespace egopd
