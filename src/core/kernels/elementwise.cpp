#include "core/kernels/elementwise.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/simd_namespace.h"
#include "core/threading.h"

namespace egopd {

// Each SIMD folder's kernels on contiguous spans (serial; the callers below split work across threads):
// avx2/ and avx512/elementwise.cpp on x86-64, neon/elementwise.cpp on AArch64.
#define EGOPD_DECLARE_SPAN_KERNELS(ns)                                   \
  namespace ns {                                                         \
  void silu_inplace(float* x, int64_t n);                                \
  void gelu_inplace(float* x, int64_t n);                                \
  void quick_gelu_inplace(float* x, int64_t n);                          \
  void erf_inplace(float* x, int64_t n);                                 \
  void geglu_row(const float* a, const float* g, int64_t d, float* out); \
  void blend_inplace(float* y, const float* x, float a, int64_t n);      \
  void add_inplace(float* y, const float* x, int64_t n);                 \
  }
EGOPD_FOR_EACH_SIMD_NS(EGOPD_DECLARE_SPAN_KERNELS)
#undef EGOPD_DECLARE_SPAN_KERNELS

namespace {


// Calls fn(begin, end) on contiguous chunks of [0, n) (64-float aligned), in parallel when n is large.
template <class Fn>
void for_chunks(int64_t n, Fn fn) {
  if (!parallel_worth(n)) {
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

// The portable span kernels.
void silu_span(float* x, int64_t n) {
  for (int64_t i = 0; i < n; ++i) x[i] = sigmoid_mul(x[i], 1.0f);
}
void gelu_span(float* x, int64_t n) {
  for (int64_t i = 0; i < n; ++i) x[i] = gelu_scalar(x[i]);
}
void quick_gelu_span(float* x, int64_t n) {
  for (int64_t i = 0; i < n; ++i) x[i] = sigmoid_mul(x[i], 1.702f);
}
void erf_span(float* x, int64_t n) {
  for (int64_t i = 0; i < n; ++i) x[i] = std::erf(x[i]);
}
void geglu_row_portable(const float* a, const float* g, int64_t d, float* out) {
  for (int64_t i = 0; i < d; ++i) out[i] = a[i] * gelu_scalar(g[i]);
}
void blend_span(float* y, const float* x, float a, int64_t n) {
  const float c = 1.0f - a;
  for (int64_t i = 0; i < n; ++i) y[i] = a * x[i] + c * y[i];
}
void add_span(float* y, const float* x, int64_t n) {
  for (int64_t i = 0; i < n; ++i) y[i] += x[i];
}

// One kernel path's span kernels.
struct SpanKernels {
  void (*silu)(float* x, int64_t n);
  void (*gelu)(float* x, int64_t n);
  void (*quick_gelu)(float* x, int64_t n);
  void (*erf)(float* x, int64_t n);
  void (*geglu_row)(const float* a, const float* g, int64_t d, float* out);
  void (*blend)(float* y, const float* x, float a, int64_t n);
  void (*add)(float* y, const float* x, int64_t n);
};

#define EGOPD_SPAN_KERNELS(ns)                                                                              \
  SpanKernels{ns::silu_inplace, ns::gelu_inplace, ns::quick_gelu_inplace, ns::erf_inplace, ns::geglu_row, \
              ns::blend_inplace, ns::add_inplace},
constexpr SpanKernels kSpanKernels[] = {
    {silu_span, gelu_span, quick_gelu_span, erf_span, geglu_row_portable, blend_span, add_span},
    EGOPD_FOR_EACH_SIMD_NS(EGOPD_SPAN_KERNELS)};
#undef EGOPD_SPAN_KERNELS

// The span kernels of the kernel path in use.
const SpanKernels& kernels() { return kSpanKernels[kernel_set_index()]; }

void map_inplace(void (*span)(float*, int64_t), float* x, int64_t n) {
  for_chunks(n, [&](int64_t b, int64_t e) { span(x + b, e - b); });
}

}  // namespace

void silu_inplace(float* x, int64_t n) { map_inplace(kernels().silu, x, n); }
void gelu_inplace(float* x, int64_t n) { map_inplace(kernels().gelu, x, n); }
void quick_gelu_inplace(float* x, int64_t n) { map_inplace(kernels().quick_gelu, x, n); }
void erf_inplace(float* x, int64_t n) { map_inplace(kernels().erf, x, n); }

void geglu_row(const float* a, const float* g, int64_t d, float* out) { kernels().geglu_row(a, g, d, out); }

void geglu(const float* p, int64_t rows, int64_t d, float* out, int64_t ldo) {
  const auto row_fn = kernels().geglu_row;
  if (ldo == 0) ldo = d;
#pragma omp parallel for schedule(static) if (parallel_worth(rows * d))
  for (int64_t r = 0; r < rows; ++r) {
    const float* a = p + r * 2 * d;  // [rows, 2d]: value half, then gate half
    row_fn(a, a + d, d, out + r * ldo);
  }
}

void upsample_nearest2x(const float* x, int64_t planes, int64_t h, int64_t w, float* y) {
#pragma omp parallel for schedule(static) if (parallel_worth(planes * h * w * 4))
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
  const auto span = kernels().blend;
  for_chunks(n, [&](int64_t b, int64_t e) { span(y + b, x + b, a, e - b); });
}

void add_inplace(float* y, const float* x, int64_t n) {
  const auto span = kernels().add;
  for_chunks(n, [&](int64_t b, int64_t e) { span(y + b, x + b, e - b); });
}

void copy_floats(float* y, const float* x, int64_t n) {
  for_chunks(n, [&](int64_t b, int64_t e) { std::memcpy(y + b, x + b, size_t(e - b) * sizeof(float)); });
}

}  // namespace egopd
