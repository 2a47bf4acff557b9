#pragma once
// Winograd transforms written once as loops over lanes (L tiles, or R output channels of the filters) with
// compile-time trip counts, so that each kernel path's file compiles them with its own instruction set (#pragma GCC
// target before including this header) and the compiler vectorises the lane loops. Everything is in an unnamed
// namespace: each path's translation unit gets its own copy, compiled for its instruction set, never merged with
// another path's by the linker. Include only from winograd.cpp and kernels/<path>/winograd.cpp.
//
// Matrices (Lavin & Gray, "Fast Algorithms for Convolutional Neural Networks", points 0, ±1, ±2 for F(4x4)):
//   F(2x2,3x3): Bᵀ = [1 0 -1 0; 0 1 1 0; 0 -1 1 0; 0 1 0 -1], G = [1 0 0; ½ ½ ½; ½ -½ ½; 0 0 1],
//               Aᵀ = [1 1 1 0; 0 1 -1 -1]
//   F(4x4,3x3): Bᵀ = [4 0 -5 0 1 0; 0 -4 -4 1 1 0; 0 4 -4 -1 1 0; 0 -2 -1 2 1 0; 0 2 -1 -2 1 0; 0 4 0 -5 0 1],
//               G = [¼ 0 0; -⅙ -⅙ -⅙; -⅙ ⅙ -⅙; 1/24 1/12 ⅙; 1/24 -1/12 ⅙; 0 0 1],
//               Aᵀ = [1 1 1 1 1 0; 0 1 -1 2 -2 0; 0 1 1 4 4 0; 0 1 -1 8 -8 1]
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "core/dtype.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"

namespace egopd::wino_detail {
namespace {

template <int M>
struct Transform;

template <>
struct Transform<2> {
  static constexpr int A = 4;
  static inline void bt(const float* d, float* v) {
    v[0] = d[0] - d[2];
    v[1] = d[1] + d[2];
    v[2] = d[2] - d[1];
    v[3] = d[1] - d[3];
  }
  static inline void g(const float* g, float* u) {
    const float h = 0.5f * (g[0] + g[2]);
    u[0] = g[0];
    u[1] = h + 0.5f * g[1];
    u[2] = h - 0.5f * g[1];
    u[3] = g[2];
  }
  static inline void at(const float* m, float* y) {
    y[0] = m[0] + m[1] + m[2];
    y[1] = m[1] - m[2] - m[3];
  }
};

template <>
struct Transform<4> {
  static constexpr int A = 6;
  static inline void bt(const float* d, float* v) {
    const float a = d[4] - 4.0f * d[2], b = d[3] - 4.0f * d[1];  // rows 1, 2
    const float c = d[4] - d[2], e = 2.0f * (d[3] - d[1]);       // rows 3, 4
    v[0] = 4.0f * d[0] - 5.0f * d[2] + d[4];
    v[1] = a + b;
    v[2] = a - b;
    v[3] = c + e;
    v[4] = c - e;
    v[5] = 4.0f * d[1] - 5.0f * d[3] + d[5];
  }
  static inline void g(const float* g, float* u) {
    constexpr float k6 = 1.0f / 6.0f, k12 = 1.0f / 12.0f, k24 = 1.0f / 24.0f;
    const float s = -k6 * (g[0] + g[2]), t = k24 * g[0] + k6 * g[2];
    u[0] = 0.25f * g[0];
    u[1] = s - k6 * g[1];
    u[2] = s + k6 * g[1];
    u[3] = t + k12 * g[1];
    u[4] = t - k12 * g[1];
    u[5] = g[2];
  }
  static inline void at(const float* m, float* y) {
    const float a = m[1] + m[2], b = m[1] - m[2], c = m[3] + m[4], d = m[3] - m[4];
    y[0] = m[0] + a + c;
    y[1] = b + 2.0f * d;
    y[2] = a + 4.0f * c;
    y[3] = b + 8.0f * d + m[5];
  }
};

// An operand value as Rounding leaves it: as is, rounded to bfloat16, or int8 quantised with factor inv and back
// with scale, as the GEMM's quantisers round (inv = scale = 0 gives 0; inv and scale are read only under Int8).
template <OperandRounding Rounding>
inline float rounded_operand(float v, float inv, float scale) {
  if constexpr (Rounding == OperandRounding::Bf16) return rounded_to_bf16(v);
  if constexpr (Rounding == OperandRounding::Int8) return gemm_detail::i8_round(v, inv) * scale;
  return v;
}

// Rounding (gemm.h, Precision): the input values are rounded to bfloat16, or quantised to int8 with the scales of
// their pixel (q), before the transform, as the direct convolution rounds its input; the transform stays float32.
template <int M, int L, OperandRounding Rounding>
void input_panel(const float* x, int64_t cin, const PanelGeom& pg, int64_t c0, int64_t c1, float* dst,
                 int64_t xi_stride, const InputQuant* q) {
  constexpr int A = Transform<M>::A;
  const int64_t h = pg.h, w = pg.w, plane = h * w;
  alignas(64) float t[A][A][L];  // row transforms: t[r][l][j] = (Bᵀ d_r)_l of tile j, d_r its input row r
  alignas(64) float vt[A][A][L];
  // A row de-interleaved: ph[k][i] = its column M*i + k (rounded), so tile i's column s is ph[s % M][i + s / M] and
  // the row transform reads whole vectors.
  alignas(64) float ph[M][L + 1] = {};
  alignas(64) float rq[M * L + 2];  // Bf16, Int8: a row segment rounded or quantised
  const int covered = pg.nseg ? pg.seg[pg.nseg - 1].j1 : 0;
  if (covered < L)
    for (int r = 0; r < A; ++r)
      for (int l = 0; l < A; ++l)
        for (int j = covered; j < L; ++j) t[r][l][j] = 0.0f;
  for (int64_t c = c0; c < c1; ++c) {
    for (int si = 0; si < pg.nseg; ++si) {
      const Segment& s = pg.seg[si];
      const int nl = s.j1 - s.j0;
      const float* xc = x + (s.f * cin + c) * plane;
      const int64_t qc = Rounding == OperandRounding::Int8 ? (s.f * q->groups + c / q->group) * plane : 0;
      for (int r = 0; r < A; ++r) {
        const int64_t iy = s.ty * M - 1 + r;
        if (iy < 0 || iy >= h) {
          for (int l = 0; l < A; ++l)
            for (int j = s.j0; j < s.j1; ++j) t[r][l][j] = 0.0f;
          continue;
        }
        const int64_t ix0 = s.tx0 * M - 1;
        const float* const row = xc + iy * w;
        if constexpr (Rounding != OperandRounding::None) {
          // The segment's columns [ix0, ix0 + span) rounded or quantised on whole vectors into rq first (zeros
          // outside the frame; the gather's single-float loads lie inside rq's vector stores, so they forward),
          // rather than each value (with its two int8 scales) as it is gathered.
          const int64_t span = M * nl + 2, lo = std::max<int64_t>(0, -ix0);
          const int64_t hi = std::clamp<int64_t>(w - ix0, lo, span);
          for (int64_t j = 0; j < lo; ++j) rq[j] = 0.0f;
          if constexpr (Rounding == OperandRounding::Int8) {
            const float* const inv = q->inv + qc + iy * w;
            const float* const scale = q->scale + qc + iy * w;
            for (int64_t j = lo; j < hi; ++j)
              rq[j] = rounded_operand<Rounding>(row[ix0 + j], inv[ix0 + j], scale[ix0 + j]);
          } else {
            for (int64_t j = lo; j < hi; ++j) rq[j] = rounded_operand<Rounding>(row[ix0 + j], 0.0f, 0.0f);
          }
          for (int64_t j = hi; j < span; ++j) rq[j] = 0.0f;
          for (int i = 0; i < nl; ++i)
            for (int k = 0; k < M; ++k) ph[k][i] = rq[M * i + k];
          ph[0][nl] = rq[M * nl];
          ph[1][nl] = rq[M * nl + 1];
        } else {
          // The row is read in place; only the tiles that reach past an edge read through a bounds check (copying
          // every row cost about a tenth of a 128-channel 256x256 convolution, copying the edge rows a twentieth:
          // at 256 columns every row segment touches an edge). Tiles [i_lo, i_hi) lie inside the frame: columns
          // ix0 + M i .. ix0 + M i + M - 1 in [0, w).
          const int i_lo = ix0 < 0 ? 1 : 0;
          const int i_hi = int(std::clamp<int64_t>((w - ix0) / M, i_lo, nl));
          const auto at = [&](int64_t col) { return col >= 0 && col < w ? row[col] : 0.0f; };
          for (int i = 0; i < i_lo; ++i)
            for (int k = 0; k < M; ++k) ph[k][i] = at(ix0 + M * i + k);
          for (int i = i_lo; i < i_hi; ++i)
            for (int k = 0; k < M; ++k) ph[k][i] = row[ix0 + M * i + k];
          for (int i = i_hi; i < nl; ++i)
            for (int k = 0; k < M; ++k) ph[k][i] = at(ix0 + M * i + k);
          ph[0][nl] = at(ix0 + M * nl);
          ph[1][nl] = at(ix0 + M * nl + 1);
        }
        for (int i = 0; i < nl; ++i) {
          float d[A], v[A];
          for (int k = 0; k < A; ++k) d[k] = ph[k % M][i + k / M];
          Transform<M>::bt(d, v);
          for (int l = 0; l < A; ++l) t[r][l][s.j0 + i] = v[l];
        }
      }
    }
    // Into a local array first: the compiler vectorises the transform only when no store can alias its inputs.
    for (int l = 0; l < A; ++l)
      for (int j = 0; j < L; ++j) {
        float d[A], v[A];
        for (int r = 0; r < A; ++r) d[r] = t[r][l][j];
        Transform<M>::bt(d, v);
        for (int k = 0; k < A; ++k) vt[k][l][j] = v[k];
      }
    for (int xi = 0; xi < A * A; ++xi) std::copy_n(&vt[xi / A][xi % A][0], L, dst + xi * xi_stride + c * L);
  }
}

template <int M, int L>
void output_panel(const float* src, int64_t xi_stride, const PanelGeom& pg, const OutputEpilogue& ep) {
  constexpr int A = Transform<M>::A;
  alignas(64) float s1[A][M][L];  // s1[k][jo][j] = (M_k Aᵀ)_jo of tile j
  alignas(64) float out[M][M][L];
  alignas(64) float row[M * L];
  for (int k = 0; k < A; ++k)
    for (int j = 0; j < L; ++j) {
      float m[A], y[M];
      for (int l = 0; l < A; ++l) m[l] = src[(k * A + l) * xi_stride + j];
      Transform<M>::at(m, y);
      for (int jo = 0; jo < M; ++jo) s1[k][jo][j] = y[jo];
    }
  for (int jo = 0; jo < M; ++jo)
    for (int j = 0; j < L; ++j) {
      float m[A], y[M];
      for (int k = 0; k < A; ++k) m[k] = s1[k][jo][j];
      Transform<M>::at(m, y);
      for (int i = 0; i < M; ++i) out[i][jo][j] = y[i] + ep.bias;
    }
  if (ep.act != Act::None) apply_act_inplace(ep.act, &out[0][0][0], M * M * L);
  const int64_t h = pg.h, w = pg.w;
  for (int si = 0; si < pg.nseg; ++si) {
    const Segment& s = pg.seg[si];
    const int64_t ox0 = s.tx0 * M;
    const int n = int(std::min<int64_t>(M * (s.j1 - s.j0), w - ox0));
    for (int i = 0; i < M; ++i) {
      const int64_t oy = s.ty * M + i;
      if (oy >= h) break;
      for (int j = s.j0; j < s.j1; ++j)
        for (int jo = 0; jo < M; ++jo) row[M * j + jo] = out[i][jo][j];
      float* d = ep.y + ((s.f * ep.cout + ep.o) * h + oy) * w + ox0;
      const float* r = row + M * s.j0;
      if (ep.accumulate)
        for (int q = 0; q < n; ++q) d[q] += r[q];
      else
        for (int q = 0; q < n; ++q) d[q] = r[q];
    }
  }
}

// The taps come rounded as the direct convolution rounds its weights (round_taps_bf16, round_taps_i8). The lane loop
// runs over RP >= R lanes (a whole number of vectors: 12 lanes took a ymm and an xmm per operation on the avx512
// path, 16 take one zmm), reading up to RP - R floats past the channel's taps (the caller's buffer has them) into
// lanes that are never stored.
template <int M, int R, int RP>
void filter_rows(const float* g, int channels, float* u, int64_t xi_stride) {
  static_assert(RP >= R && RP - R <= kFilterOverread);
  constexpr int A = Transform<M>::A;
  // Channels staged in groups, then each tile position's run written out whole: storing each channel's R floats to
  // all A*A positions in turn kept A*A partial-line store streams open, and their misses stalled the transform (bench
  // conv2d 1280->1280 on 16 x 8x8, AMD EPYC Zen 4: 1.07-1.52x faster). A group's stage stays within 16 KiB of L1.
  // Channel c's spare lanes land on channel c + 1's, which its own stores then overwrite.
  constexpr int G = std::clamp(16384 / (A * A * R * 4) / 4 * 4, 4, kMaxLanes);
  alignas(64) float ut[A * A][G * R + RP];
  for (int c0 = 0; c0 < channels; c0 += G) {
    const int gc = std::min(G, channels - c0);
    for (int c = 0; c < gc; ++c) {
      const float* const gt = g + (c0 + c) * 9 * R;
      for (int j = 0; j < RP; ++j) {
        float t[3][A];  // t[p][l] = (g_p Gᵀ)_l, g_p row p of the 3x3 kernel
        for (int p = 0; p < 3; ++p) {
          const float row[3] = {gt[(p * 3) * R + j], gt[(p * 3 + 1) * R + j], gt[(p * 3 + 2) * R + j]};
          Transform<M>::g(row, t[p]);
        }
        for (int l = 0; l < A; ++l) {
          const float col[3] = {t[0][l], t[1][l], t[2][l]};
          float v[A];
          Transform<M>::g(col, v);
          for (int k = 0; k < A; ++k) ut[k * A + l][c * R + j] = v[k];
        }
      }
    }
    for (int xi = 0; xi < A * A; ++xi) std::copy_n(ut[xi], gc * R, u + xi * xi_stride + c0 * R);
  }
}

// Bf16: the taps of a whole item rounded in one vectorised pass before their transforms (rounding each tap as the
// transform loaded it made the bf16 filter transform 1.3-1.8x the float32 one: perf, AMD EPYC Zen 4). The pass
// ends long before the transforms read its first values back, so its vector stores do not stall their loads.
inline void round_taps_bf16(float* g, int64_t n) {
  for (int64_t i = 0; i < n; ++i) g[i] = rounded_to_bf16(g[i]);
}

// The taps of a whole item (up to L input channels) quantised in one vectorised pass before their transforms, rather
// than each tap as the transform loads it (perf, 1280 channels on 16 x 8x8 frames, AMD EPYC Zen 3, alternating: the
// transforms' samples 0.39-0.55 of the micro-kernel's -> 0.31-0.32 in three rounds of four). Lane i of flat index
// f = k * R + i is f % R: over a group's run the scales repeat with period R, laid out as P = lcm(R, 16) floats so
// that the loop runs on whole vectors.
template <int R>
void round_taps_i8(float* g, int64_t k0, int64_t nk, const TapScales& s) {
  constexpr int P = R * 16 / std::gcd(R, 16);
  alignas(64) float inv[P], scale[P];
  for (int64_t k = k0, k1; k < k0 + nk; k = k1) {
    const int64_t grp = k / s.group;
    k1 = std::min(k0 + nk, (grp + 1) * s.group);
    for (int m = 0; m < P; ++m) {
      inv[m] = s.inv[grp * s.ld + m % R];
      scale[m] = s.scale[grp * s.ld + m % R];
    }
    float* const v = g + (k - k0) * R;
    const int64_t n = (k1 - k) * R;
    int64_t f = 0;
    for (; f + P <= n; f += P)
      for (int m = 0; m < P; ++m) v[f + m] = rounded_operand<OperandRounding::Int8>(v[f + m], inv[m], scale[m]);
    for (; f < n; ++f) v[f] = rounded_operand<OperandRounding::Int8>(v[f], inv[f % P], scale[f % P]);
  }
}

template <int L, int R, OperandRounding Rounding>
void set_rounding(WinogradKernels& k) {
  k.input[int(Rounding)][0] = input_panel<2, L, Rounding>;
  k.input[int(Rounding)][1] = input_panel<4, L, Rounding>;
}

template <int L, int R>
WinogradKernels make_winograd_kernels() {
  WinogradKernels k;
  k.lanes = L;
  k.rows = R;
  set_rounding<L, R, OperandRounding::None>(k);
  set_rounding<L, R, OperandRounding::Bf16>(k);
  set_rounding<L, R, OperandRounding::Int8>(k);
  constexpr int RP = (R + 7) / 8 * 8;
  k.filter[0] = filter_rows<2, R, RP>;
  k.filter[1] = filter_rows<4, R, RP>;
  k.output[0] = output_panel<2, L>;
  k.output[1] = output_panel<4, L>;
  k.round_taps_bf16 = round_taps_bf16;
  k.round_taps_i8 = round_taps_i8<R>;
  return k;
}

}  // namespace
}  // namespace egopd::wino_detail
