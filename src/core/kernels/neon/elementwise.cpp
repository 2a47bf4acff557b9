// NEON element-wise kernels on contiguous spans (the caller splits work across threads).
#include <cstdint>

#include "core/kernels/neon/vec_math.h"

namespace egopd::neon {

using namespace egopd::nmath;

namespace {

enum Op { kSilu, kGelu, kQuickGelu, kErf };

template <int OP>
inline float32x4_t apply(float32x4_t v) {
  if (OP == kSilu) return silu_v(v);
  if (OP == kGelu) return gelu_v(v);
  if (OP == kQuickGelu) return x_sigmoid_v(v, 1.702f);
  return erf_v(v);
}

template <int OP>
void map_inplace(float* x, int64_t n) {
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) vst1q_f32(x + i, apply<OP>(vld1q_f32(x + i)));
  if (i < n) store_tail(x + i, apply<OP>(load_tail(x + i, n - i)), n - i);
}

}  // namespace

void silu_inplace(float* x, int64_t n) { map_inplace<kSilu>(x, n); }
void gelu_inplace(float* x, int64_t n) { map_inplace<kGelu>(x, n); }
void quick_gelu_inplace(float* x, int64_t n) { map_inplace<kQuickGelu>(x, n); }
void erf_inplace(float* x, int64_t n) { map_inplace<kErf>(x, n); }

// One row of GEGLU: out[i] = a[i] * GELU(g[i]).
void geglu_row(const float* a, const float* g, int64_t d, float* out) {
  int64_t i = 0;
  for (; i + 4 <= d; i += 4) vst1q_f32(out + i, vmulq_f32(vld1q_f32(a + i), gelu_v(vld1q_f32(g + i))));
  if (i < d) store_tail(out + i, vmulq_f32(load_tail(a + i, d - i), gelu_v(load_tail(g + i, d - i))), d - i);
}

void blend_inplace(float* y, const float* x, float a, int64_t n) {
  const float32x4_t va = vdupq_n_f32(a), vb = vdupq_n_f32(1.0f - a);
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) vst1q_f32(y + i, vfmaq_f32(vmulq_f32(vb, vld1q_f32(y + i)), va, vld1q_f32(x + i)));
  for (; i < n; ++i) y[i] = a * x[i] + (1.0f - a) * y[i];
}

void add_inplace(float* y, const float* x, int64_t n) {
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) vst1q_f32(y + i, vaddq_f32(vld1q_f32(y + i), vld1q_f32(x + i)));
  for (; i < n; ++i) y[i] += x[i];
}

}  // namespace egopd::neon
