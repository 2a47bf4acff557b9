// NEON row kernels for the normalisations (the caller splits work across threads); the algorithms of avx2/norm.cpp.
#include <cstdint>

#include "core/kernels/neon/vec_math.h"

namespace egopd::neon {

using namespace egopd::nmath;

// Accumulates sum(x - shift) and sum((x - shift)^2) over n floats in double precision.
void shifted_sums(const float* x, int64_t n, double shift, double* sum, double* sumsq) {
  const float64x2_t k = vdupq_n_f64(shift);
  float64x2_t s0 = vdupq_n_f64(0.0), s1 = s0, q0 = s0, q1 = s0;
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) {
    const float32x4_t v = vld1q_f32(x + i);
    const float64x2_t d0 = vsubq_f64(vcvt_f64_f32(vget_low_f32(v)), k);
    const float64x2_t d1 = vsubq_f64(vcvt_high_f64_f32(v), k);
    s0 = vaddq_f64(s0, d0), s1 = vaddq_f64(s1, d1);
    q0 = vfmaq_f64(q0, d0, d0), q1 = vfmaq_f64(q1, d1, d1);
  }
  double s = vaddvq_f64(vaddq_f64(s0, s1)), q = vaddvq_f64(vaddq_f64(q0, q1));
  for (; i < n; ++i) {
    const double d = static_cast<double>(x[i]) - shift;
    s += d, q += d * d;
  }
  *sum += s, *sumsq += q;
}

// y = (x - mean) * scale + shift, optionally followed by SiLU.
void affine_span(const float* x, float* y, int64_t n, float mean, float scale, float shift, bool silu) {
  const float32x4_t m0 = vdupq_n_f32(mean), a = vdupq_n_f32(scale), b = vdupq_n_f32(shift);
  int64_t i = 0;
  if (silu) {
    for (; i + 4 <= n; i += 4) vst1q_f32(y + i, silu_v(vfmaq_f32(b, vsubq_f32(vld1q_f32(x + i), m0), a)));
  } else {
    for (; i + 4 <= n; i += 4) vst1q_f32(y + i, vfmaq_f32(b, vsubq_f32(vld1q_f32(x + i), m0), a));
  }
  if (i < n) {
    float32x4_t v = vfmaq_f32(b, vsubq_f32(load_tail(x + i, n - i), m0), a);
    if (silu) v = silu_v(v);
    store_tail(y + i, v, n - i);
  }
}

// LayerNorm of one row: pass 1 a float mean m0; pass 2 sums d = x - m0 and d^2, which corrects the mean
// (m = m0 + mean(d)) and gives the biased variance mean(d^2) - mean(d)^2 without cancellation.
void layer_norm_row(const float* x, float* y, int64_t c, const float* gamma, const float* beta, float eps) {
  float32x4_t s0 = vdupq_n_f32(0.0f), s1 = s0, s2 = s0, s3 = s0;
  int64_t i = 0;
  for (; i + 16 <= c; i += 16) {
    s0 = vaddq_f32(s0, vld1q_f32(x + i)), s1 = vaddq_f32(s1, vld1q_f32(x + i + 4));
    s2 = vaddq_f32(s2, vld1q_f32(x + i + 8)), s3 = vaddq_f32(s3, vld1q_f32(x + i + 12));
  }
  for (; i + 4 <= c; i += 4) s0 = vaddq_f32(s0, vld1q_f32(x + i));
  const int64_t tail = c - c / 4 * 4;
  if (tail) s1 = vaddq_f32(s1, load_tail(x + i, tail));
  const float inv_c = 1.0f / static_cast<float>(c);
  const float m0 = vaddvq_f32(vaddq_f32(vaddq_f32(s0, s1), vaddq_f32(s2, s3))) * inv_c;

  const float32x4_t vm0 = vdupq_n_f32(m0);
  float32x4_t d0 = vdupq_n_f32(0.0f), d1 = d0, q0 = d0, q1 = d0;
  for (i = 0; i + 8 <= c; i += 8) {
    const float32x4_t a = vsubq_f32(vld1q_f32(x + i), vm0), b = vsubq_f32(vld1q_f32(x + i + 4), vm0);
    d0 = vaddq_f32(d0, a), d1 = vaddq_f32(d1, b);
    q0 = vfmaq_f32(q0, a, a), q1 = vfmaq_f32(q1, b, b);
  }
  for (; i + 4 <= c; i += 4) {
    const float32x4_t a = vsubq_f32(vld1q_f32(x + i), vm0);
    d0 = vaddq_f32(d0, a), q0 = vfmaq_f32(q0, a, a);
  }
  float dsum = vaddvq_f32(vaddq_f32(d0, d1)), qsum = vaddvq_f32(vaddq_f32(q0, q1));
  for (; i < c; ++i) {
    const float a = x[i] - m0;
    dsum += a, qsum += a * a;
  }
  const float dmean = dsum * inv_c;
  const float var = qsum * inv_c - dmean * dmean;
  const float32x4_t vm = vdupq_n_f32(m0 + dmean);
  const float rstd_s = 1.0f / __builtin_sqrtf((var > 0.0f ? var : 0.0f) + eps);
  const float32x4_t rstd = vdupq_n_f32(rstd_s);

  for (i = 0; i + 4 <= c; i += 4) {
    float32x4_t v = vmulq_f32(vsubq_f32(vld1q_f32(x + i), vm), rstd);
    if (gamma) v = vmulq_f32(v, vld1q_f32(gamma + i));
    if (beta) v = vaddq_f32(v, vld1q_f32(beta + i));
    vst1q_f32(y + i, v);
  }
  for (; i < c; ++i) {
    float v = (x[i] - (m0 + dmean)) * rstd_s;
    if (gamma) v *= gamma[i];
    if (beta) v += beta[i];
    y[i] = v;
  }
}

// Stable softmax of one row in place: max, exp(x - max) with the sum, scale by 1/sum.
void softmax_row(float* x, int64_t n) {
  float32x4_t mx = vdupq_n_f32(-__builtin_inff());
  int64_t i = 0;
  for (; i + 4 <= n; i += 4) mx = vmaxq_f32(mx, vld1q_f32(x + i));
  float m = vmaxvq_f32(mx);
  for (int64_t j = i; j < n; ++j) m = x[j] > m ? x[j] : m;
  const float32x4_t inv = vdupq_n_f32(1.0f / exp_shifted_sum(x, n, m));
  for (i = 0; i + 4 <= n; i += 4) vst1q_f32(x + i, vmulq_f32(vld1q_f32(x + i), inv));
  for (; i < n; ++i) x[i] *= vgetq_lane_f32(inv, 0);
}

}  // namespace egopd::neon
