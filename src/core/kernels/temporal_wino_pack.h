#pragma once
// The B packer of the temporal Winograd (conv_temporal.cpp), the input transform Bᵀd of F(2,3) or F(4,3) along
// time, and its output transform, written as plain loops over compile-time panel widths so that each kernel path's
// file compiles them with its own vector instructions (include after that file's `#pragma GCC target`; everything is
// file-local).
#include <cstdint>

namespace egopd::gemm_detail {
namespace {

// One row of the transform over columns [0, n): plain loops on restrict pointer parameters, which the compiler
// vectorises (GCC 12 leaves the same loops scalar when the restrict pointers are locals copied from an array: the
// input transform ran one float at a time). F(2,3) uses the first four of each.
template <int M>
inline void temporal_wino_row(const float* __restrict d0, const float* __restrict d1, const float* __restrict d2,
                              const float* __restrict d3, const float* __restrict d4, const float* __restrict d5,
                              float* __restrict v0, float* __restrict v1, float* __restrict v2, float* __restrict v3,
                              float* __restrict v4, float* __restrict v5, int n) {
  if constexpr (M == 2) {
    for (int j = 0; j < n; ++j) {
      v0[j] = d0[j] - d2[j];
      v1[j] = d1[j] + d2[j];
      v2[j] = d2[j] - d1[j];
      v3[j] = d1[j] - d3[j];
    }
  } else {
    for (int j = 0; j < n; ++j) {
      const float s12 = d1[j] + d2[j], t12 = d1[j] - d2[j], u42 = d4[j] - d2[j], u31 = d3[j] - d1[j];
      v0[j] = 4.0f * d0[j] - 5.0f * d2[j] + d4[j];
      v1[j] = (d3[j] + d4[j]) - 4.0f * s12;
      v2[j] = (d4[j] - d3[j]) + 4.0f * t12;
      v3[j] = u42 + 2.0f * u31;
      v4[j] = u42 - 2.0f * u31;
      v5[j] = 4.0f * d1[j] - 5.0f * d3[j] + d5[j];
    }
  }
}
template <int M>
inline void temporal_wino_row(const float* const (&d)[6], float* const (&v)[6], int n) {
  temporal_wino_row<M>(d[0], d[1], d[2], d[3], d[4], d[5], v[0], v[1], v[2], v[3], v[4], v[5], n);
}

// Panel i (at dst + i * panel_floats) gets row k, column j of V_i = (Bᵀ d)_i, d_t = in[t][k*ld[t] + j], for j < nr,
// zero for nr <= j < NR; m + 2 inputs (a frame outside the video is a zero row with ld 0).
//   F(2,3): V = (d0 - d2, d1 + d2, d2 - d1, d1 - d3)
//   F(4,3): V = (4d0 - 5d2 + d4, (d3 + d4) - 4(d1 + d2), (d4 - d3) + 4(d1 - d2), (d4 - d2) + 2(d3 - d1),
//                (d4 - d2) - 2(d3 - d1), 4d1 - 5d3 + d5)
template <int NR, int M>
void temporal_wino_rows(const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                        int64_t panel_floats) {
  constexpr int A = M + 2;
  for (int64_t k = 0; k < kc; ++k) {
    const float* d[6] = {};
    float* v[6] = {};
    for (int t = 0; t < A; ++t) {
      d[t] = in[t] + k * ld[t], v[t] = dst + t * panel_floats + k * NR;
      // The rows of a frame lie a frame's width apart, A frames at once: more strided streams than the hardware
      // prefetcher follows (measured: 128 channels of 256x256 frames 8-15% slower without).
      for (int j = 0; j < NR; j += 16) __builtin_prefetch(d[t] + 4 * ld[t] + j);
    }
    if (nr == NR) {
      temporal_wino_row<M>(d, v, NR);
    } else {
      temporal_wino_row<M>(d, v, nr);
      for (int t = 0; t < A; ++t)
        for (int j = nr; j < NR; ++j) v[t][j] = 0.0f;
    }
  }
}

template <int NR>
void temporal_wino_pack(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                        int64_t panel_floats) {
  if (m == 2) temporal_wino_rows<NR, 2>(in, ld, kc, nr, dst, panel_floats);
  else temporal_wino_rows<NR, 4>(in, ld, kc, nr, dst, panel_floats);
}

// o[j] = f(j) + b, or o[j] += f(j) + b, for j < n (n = NR: a compile-time trip count, whole vectors).
template <int NR, class F>
inline void temporal_wino_put(float* o, int n, float b, bool accumulate, F f) {
  const auto run = [&](int len) {
    if (accumulate)
      for (int j = 0; j < len; ++j) o[j] += f(j) + b;
    else
      for (int j = 0; j < len; ++j) o[j] = f(j) + b;
  };
  if (n == NR) run(NR);
  else run(n);
}

// Output frame t of one micro-tile row from the products m[i][j] (vectorised behind a run-time check that o does
// not overlap them):
//   F(2,3): y = (M0 + M1 + M2, M1 - M2 - M3)
//   F(4,3): y = (M0 + (M1 + M2) + (M3 + M4), (M1 - M2) + 2(M3 - M4), (M1 + M2) + 4(M3 + M4),
//                (M1 - M2) + 8(M3 - M4) + M5)
template <int NR, int M>
inline void temporal_wino_out_row(int t, const float* const (&m)[6], int n, float b, bool accumulate, float* o) {
  const float *m0 = m[0], *m1 = m[1], *m2 = m[2], *m3 = m[3], *m4 = m[4], *m5 = m[5];
  if constexpr (M == 2) {
    if (t == 0) temporal_wino_put<NR>(o, n, b, accumulate, [&](int j) { return m0[j] + m1[j] + m2[j]; });
    else temporal_wino_put<NR>(o, n, b, accumulate, [&](int j) { return m1[j] - m2[j] - m3[j]; });
  } else if (t == 0) {
    temporal_wino_put<NR>(o, n, b, accumulate, [&](int j) { return m0[j] + (m1[j] + m2[j]) + (m3[j] + m4[j]); });
  } else if (t == 1) {
    temporal_wino_put<NR>(o, n, b, accumulate, [&](int j) { return (m1[j] - m2[j]) + 2.0f * (m3[j] - m4[j]); });
  } else if (t == 2) {
    temporal_wino_put<NR>(o, n, b, accumulate, [&](int j) { return (m1[j] + m2[j]) + 4.0f * (m3[j] + m4[j]); });
  } else {
    temporal_wino_put<NR>(o, n, b, accumulate,
                          [&](int j) { return (m1[j] - m2[j]) + 8.0f * (m3[j] - m4[j]) + m5[j]; });
  }
}

// The output transform of one micro-tile of F(m,3): products M_i at prod + i * prod_stride (row r at + r * NR);
// frame t < frames, row r < mr of the tile, lanes j < nr, to dst[t * frame_stride + r * row_stride + j] (added to
// it with `accumulate`), plus bias[r] (bias may be null).
template <int NR>
void temporal_wino_out(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr, const float* bias,
                       bool accumulate, float* dst, int64_t frame_stride, int64_t row_stride) {
  for (int r = 0; r < mr; ++r) {  // a row's products and bias serve all its frames
    const float* rows[6] = {};
    for (int i = 0; i < m + 2; ++i) rows[i] = prod + i * prod_stride + r * NR;
    const float b = bias ? bias[r] : 0.0f;
    for (int t = 0; t < frames; ++t) {
      float* const o = dst + t * frame_stride + r * row_stride;
      if (m == 2) temporal_wino_out_row<NR, 2>(t, rows, nr, b, accumulate, o);
      else temporal_wino_out_row<NR, 4>(t, rows, nr, b, accumulate, o);
    }
  }
}

}  // namespace
}  // namespace egopd::gemm_detail
