// NEON attention row: one query of one head against its keys (the caller, attention.cpp, runs the rows of every
// head and batch in parallel). Scores four keys at a time, a stable softmax with the vector exp, then P.V four
// channels at a time.
#include <cstdint>

#include "core/kernels/neon/vec_math.h"

namespace egopd::neon {

using namespace egopd::nmath;

namespace {

// q . k over n floats, four keys at a time: out[r] = q . k_r.
inline void dot4(const float* q, const float* k0, const float* k1, const float* k2, const float* k3, int64_t n,
                 float* out) {
  float32x4_t a0 = vdupq_n_f32(0.0f), a1 = a0, a2 = a0, a3 = a0;
  int64_t d = 0;
  for (; d + 4 <= n; d += 4) {
    const float32x4_t qv = vld1q_f32(q + d);
    a0 = vfmaq_f32(a0, qv, vld1q_f32(k0 + d));
    a1 = vfmaq_f32(a1, qv, vld1q_f32(k1 + d));
    a2 = vfmaq_f32(a2, qv, vld1q_f32(k2 + d));
    a3 = vfmaq_f32(a3, qv, vld1q_f32(k3 + d));
  }
  float s0 = vaddvq_f32(a0), s1 = vaddvq_f32(a1), s2 = vaddvq_f32(a2), s3 = vaddvq_f32(a3);
  for (; d < n; ++d) s0 += q[d] * k0[d], s1 += q[d] * k1[d], s2 += q[d] * k2[d], s3 += q[d] * k3[d];
  out[0] = s0, out[1] = s1, out[2] = s2, out[3] = s3;
}

}  // namespace

// p: nk floats of workspace; out: dh floats.
void attend_row(const float* q, const float* k, int64_t k_ld, const float* v, int64_t v_ld, int64_t nk, int64_t dh,
                float scale, float* p, float* out) {
  int64_t j = 0;
  for (; j + 4 <= nk; j += 4)
    dot4(q, k + j * k_ld, k + (j + 1) * k_ld, k + (j + 2) * k_ld, k + (j + 3) * k_ld, dh, p + j);
  for (; j < nk; ++j) {  // the last keys: the row repeated in the unused slots
    float s[4];
    const float* kj = k + j * k_ld;
    dot4(q, kj, kj, kj, kj, dh, s);
    p[j] = s[0];
  }
  const float32x4_t vs = vdupq_n_f32(scale);
  float32x4_t mx = vdupq_n_f32(-__builtin_inff());
  for (j = 0; j + 4 <= nk; j += 4) {
    const float32x4_t sv = vmulq_f32(vld1q_f32(p + j), vs);
    vst1q_f32(p + j, sv);
    mx = vmaxq_f32(mx, sv);
  }
  float m = vmaxvq_f32(mx);
  for (; j < nk; ++j) {
    p[j] *= scale;
    m = p[j] > m ? p[j] : m;
  }
  const float inv = 1.0f / exp_shifted_sum(p, nk, m);
  // out = sum_j p[j] v_j, 16 channels (four registers) at a time, then the rest.
  int64_t d = 0;
  for (; d + 16 <= dh; d += 16) {
    float32x4_t o0 = vdupq_n_f32(0.0f), o1 = o0, o2 = o0, o3 = o0;
    for (j = 0; j < nk; ++j) {
      const float* vr = v + j * v_ld + d;
      const float32x4_t pj = vdupq_n_f32(p[j]);
      o0 = vfmaq_f32(o0, pj, vld1q_f32(vr)), o1 = vfmaq_f32(o1, pj, vld1q_f32(vr + 4));
      o2 = vfmaq_f32(o2, pj, vld1q_f32(vr + 8)), o3 = vfmaq_f32(o3, pj, vld1q_f32(vr + 12));
    }
    const float32x4_t vi = vdupq_n_f32(inv);
    vst1q_f32(out + d, vmulq_f32(o0, vi)), vst1q_f32(out + d + 4, vmulq_f32(o1, vi));
    vst1q_f32(out + d + 8, vmulq_f32(o2, vi)), vst1q_f32(out + d + 12, vmulq_f32(o3, vi));
  }
  for (; d + 4 <= dh; d += 4) {
    float32x4_t o0 = vdupq_n_f32(0.0f);
    for (j = 0; j < nk; ++j) o0 = vfmaq_f32(o0, vdupq_n_f32(p[j]), vld1q_f32(v + j * v_ld + d));
    vst1q_f32(out + d, vmulq_f32(o0, vdupq_n_f32(inv)));
  }
  for (; d < dh; ++d) {
    float o = 0.0f;
    for (j = 0; j < nk; ++j) o += p[j] * v[j * v_ld + d];
    out[d] = o * inv;
  }
}

}  // namespace egopd::neon
