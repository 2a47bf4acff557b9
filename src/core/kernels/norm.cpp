#include "core/kernels/norm.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/simd_namespace.h"
#include "core/threading.h"

namespace egopd {

// Each SIMD folder's row kernels (serial; the callers below split work across threads): avx2/ and avx512/norm.cpp
// on x86-64, neon/norm.cpp on AArch64.
#define EGOPD_DECLARE_ROW_KERNELS(ns)                                                                         \
  namespace ns {                                                                                              \
  void shifted_sums(const float* x, int64_t n, double shift, double* sum, double* sumsq);                     \
  void affine_span(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu);     \
  void layer_norm_row(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps); \
  void softmax_row(float* x, int64_t n);                                                                      \
  }
EGOPD_FOR_EACH_SIMD_NS(EGOPD_DECLARE_ROW_KERNELS)
#undef EGOPD_DECLARE_ROW_KERNELS

namespace {

bool run_parallel(int64_t units, int64_t n) { return units > 1 && parallel_worth(n); }

float silu_scalar(float v) { return v / (1.0f + std::exp(-v)); }

void shifted_sums_portable(const float* x, int64_t n, double shift, double* sum, double* sumsq) {
  double s = 0.0, q = 0.0;
  for (int64_t i = 0; i < n; ++i) {
    const double d = static_cast<double>(x[i]) - shift;
    s += d, q += d * d;
  }
  *sum += s, *sumsq += q;
}

void affine_span_portable(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu) {
  for (int64_t i = 0; i < n; ++i) {
    const float v = (x[i] - mean) * scale + shift;
    y[i] = silu ? silu_scalar(v) : v;
  }
}

void layer_norm_row_portable(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps) {
  double sum = 0.0;
  for (int64_t i = 0; i < c; ++i) sum += x[i];
  const double mean = sum / static_cast<double>(c);
  double sq = 0.0;
  for (int64_t i = 0; i < c; ++i) {
    const double d = x[i] - mean;
    sq += d * d;
  }
  const float rstd = static_cast<float>(1.0 / std::sqrt(sq / static_cast<double>(c) + static_cast<double>(eps)));
  const float m = static_cast<float>(mean);
  for (int64_t i = 0; i < c; ++i) {
    const float v = (x[i] - m) * rstd;
    y[i] = v * (gamma ? gamma[i] : 1.0f) + (beta ? beta[i] : 0.0f);
  }
}

void softmax_row_portable(float* p, int64_t cols) {
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

// One kernel path's row kernels.
struct RowKernels {
  void (*shifted_sums)(const float* x, int64_t n, double shift, double* sum, double* sumsq);
  void (*affine_span)(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu);
  void (*layer_norm_row)(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps);
  void (*softmax_row)(float* x, int64_t n);
};

#define EGOPD_ROW_KERNELS(ns) RowKernels{ns::shifted_sums, ns::affine_span, ns::layer_norm_row, ns::softmax_row},
constexpr RowKernels kRowKernels[] = {
    {shifted_sums_portable, affine_span_portable, layer_norm_row_portable, softmax_row_portable},
    EGOPD_FOR_EACH_SIMD_NS(EGOPD_ROW_KERNELS)};
#undef EGOPD_ROW_KERNELS

// The row kernels of the kernel path in use.
const RowKernels& kernels() { return kRowKernels[kernel_set_index()]; }

}  // namespace

void group_norm(const float* x, float* y, int64_t batch, int64_t frames, int64_t c, int64_t s, int64_t groups,
                const float* gamma, const float* beta, float eps, bool silu) {
  EGOPD_CHECK(groups > 0 && c % groups == 0, "group_norm: " + std::to_string(c) + " channels in " +
                                                  std::to_string(groups) + " groups");
  const int64_t cg = c / groups;
  const int64_t units = batch * groups;
  const auto sums = kernels().shifted_sums;
  const auto affine = kernels().affine_span;
#pragma omp parallel for schedule(dynamic, 1) if (run_parallel(units, batch * frames * c * s))
  for (int64_t u = 0; u < units; ++u) {
    const int64_t b = u / groups, g = u % groups;
    const float* xg = x + b * frames * c * s + g * cg * s;  // group g of frame 0; frames are c*s apart
    float* yg = y + b * frames * c * s + g * cg * s;
    // Statistics over frames x cg x s values in double, shifted by the first value against cancellation.
    const double shift = xg[0];
    double sum = 0.0, sumsq = 0.0;
    for (int64_t f = 0; f < frames; ++f) sums(xg + f * c * s, cg * s, shift, &sum, &sumsq);
    const double n = static_cast<double>(frames * cg * s);
    const double mean_shifted = sum / n;
    const double var = std::max(0.0, sumsq / n - mean_shifted * mean_shifted);  // biased variance
    const double mean = shift + mean_shifted;
    const float mean_f = static_cast<float>(mean);
    const double rstd = 1.0 / std::sqrt(var + static_cast<double>(eps));
    for (int64_t ci = 0; ci < cg; ++ci) {
      const int64_t ch = g * cg + ci;
      const float scale = static_cast<float>(rstd * (gamma ? gamma[ch] : 1.0f));
      const float shift_out = beta ? beta[ch] : 0.0f;
      for (int64_t f = 0; f < frames; ++f)
        affine(xg + f * c * s + ci * s, yg + f * c * s + ci * s, s, mean_f, scale, shift_out, silu);
    }
  }
}

void layer_norm(const float* x, float* y, int64_t rows, int64_t c, const float* gamma, const float* beta, float eps) {
  const auto row_fn = kernels().layer_norm_row;
#pragma omp parallel for schedule(static) if (run_parallel(rows, rows * c))
  for (int64_t r = 0; r < rows; ++r) row_fn(x + r * c, y + r * c, c, gamma, beta, eps);
}

void softmax_rows(float* x, int64_t rows, int64_t cols) {
  const auto row_fn = kernels().softmax_row;
#pragma omp parallel for schedule(static) if (run_parallel(rows, rows * cols))
  for (int64_t r = 0; r < rows; ++r) row_fn(x + r * cols, cols);
}

}  // namespace egopd
