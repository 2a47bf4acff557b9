#include "core/kernels/attention.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "core/cpu.h"
#include "core/dtype.h"
#include "core/error.h"
#include "core/kernels/gemm.h"
#include "core/kernels/kernel_profile.h"
#include "core/memory.h"
#include "core/tensor.h"

namespace egopd {

#if defined(__aarch64__)
namespace neon {  // neon/attention.cpp: attend_row below, vectorised
void attend_row(const float* q, const float* k, int64_t k_ld, const float* v, int64_t v_ld, int64_t nk, int64_t dh,
                float scale, float* p, float* out);
}  // namespace neon
#else
// The blocked x86 kernels, one interface: avx2/attention.cpp and avx512/attention.cpp.
namespace avx2 {
int64_t attention_tile_queries();
int64_t attention_tile_workspace(int64_t dh);
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16);
void prefetch_unit(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq);
}  // namespace avx2
namespace avx512 {
int64_t attention_tile_queries();
int64_t attention_tile_workspace(int64_t dh);
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16);
// Precision::Bf16 on vdpbf16ps: per (batch, head) the keys and values as bfloat16 pairs (operand_slots 32-bit
// slots, written by prepare), then the query tiles against them.
int64_t attention_bf16_operand_slots(int64_t lk, int64_t dh);
void attention_bf16_prepare(const AttentionArgs& a, int64_t b, int64_t h, uint32_t* ops);
int64_t attention_bf16_workspace(int64_t dh);
void attention_tile_bf16(const AttentionArgs& a, const uint32_t* ops, int64_t b, int64_t h, int64_t q0, int64_t nq,
                         float* work);
}  // namespace avx512
#endif

namespace {

// q . k with 8 independent partial sums (the compiler may keep them in SIMD registers).
float dot(const float* q, const float* k, int64_t n) {
  float acc[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int64_t d = 0;
  for (; d + 8 <= n; d += 8)
    for (int u = 0; u < 8; ++u) acc[u] += q[d + u] * k[d + u];
  float s = ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]));
  for (; d < n; ++d) s += q[d] * k[d];
  return s;
}

// Scores of one query row against its nk keys into p [nk], times c; returns their max.
float row_scores(const float* q, const float* k, int64_t k_ld, int64_t nk, int64_t dh, float c, float* p) {
  float mx = -INFINITY;
  for (int64_t j = 0; j < nk; ++j) {
    p[j] = dot(q, k + j * k_ld, dh) * c;
    mx = std::max(mx, p[j]);
  }
  return mx;
}

// out [dh] = sum_j p[j] v_j / sum.
void weighted_rows(const float* p, const float* v, int64_t v_ld, int64_t nk, int64_t dh, float sum, float* out) {
  std::fill(out, out + dh, 0.0f);
  for (int64_t j = 0; j < nk; ++j) {
    const float* vr = v + j * v_ld;
    const float pj = p[j];
    for (int64_t d = 0; d < dh; ++d) out[d] += pj * vr[d];
  }
  const float inv = 1.0f / sum;
  for (int64_t d = 0; d < dh; ++d) out[d] *= inv;
}

// One query row of one head against its nk keys: scores into p [nk], stable softmax, then P.V into out.
void attend_row(const float* q, const float* k, int64_t k_ld, const float* v, int64_t v_ld, int64_t nk, int64_t dh,
                float scale, float* p, float* out) {
  const float mx = row_scores(q, k, k_ld, nk, dh, scale, p);
  float sum = 0.0f;
  for (int64_t j = 0; j < nk; ++j) sum += (p[j] = std::exp(p[j] - mx));
  weighted_rows(p, v, v_ld, nk, dh, sum, out);
}

// The same under Precision::Bf16 (attention.h), on q, k and v already rounded to bfloat16: scores in the log2
// domain, an integral max, P rounded to bfloat16. The emulation of the paths without a blocked kernel.
void attend_row_bf16(const float* q, const float* k, int64_t k_ld, const float* v, int64_t v_ld, int64_t nk,
                     int64_t dh, float scale, float* p, float* out) {
  const float m = std::ceil(row_scores(q, k, k_ld, nk, dh, scale * 1.44269504088896341f, p));
  float sum = 0.0f;
  for (int64_t j = 0; j < nk; ++j) sum += (p[j] = rounded_to_bf16(std::exp2(p[j] - m)));
  weighted_rows(p, v, v_ld, nk, dh, sum, out);
}

bool bf16_native_allowed = true;  // set_attention_bf16_native

// Precision::Bf16 emulated: q, k and v rounded to bfloat16 into compact copies ([batch][rows][heads * dh]), which
// `rounded` points at (the emulating kernels then round P themselves).
struct RoundedOperands {
  AttentionArgs rounded;
  explicit RoundedOperands(const AttentionArgs& a) : rounded(a) {
    const int64_t C = a.heads * a.dh;
    thread_local AlignedScratch buf;
    float* q = buf.get(size_t(a.batch * (a.lq + 2 * a.lk) * C));
    float* k = q + a.batch * a.lq * C;
    float* v = k + a.batch * a.lk * C;
    copy(a.q, a.q_ld, a.q_bs, a.lq, q);
    copy(a.k, a.k_ld, a.k_bs, a.lk, k);
    copy(a.v, a.v_ld, a.v_bs, a.lk, v);
    rounded.q = q, rounded.k = k, rounded.v = v;
    rounded.q_ld = rounded.k_ld = rounded.v_ld = C;
    rounded.q_bs = a.lq * C, rounded.k_bs = rounded.v_bs = a.lk * C;
  }
  void copy(const float* src, int64_t ld, int64_t bs, int64_t rows, float* dst) const {
    const int64_t C = rounded.heads * rounded.dh, n = rounded.batch * rows;
#pragma omp parallel for schedule(static) if (!omp_in_parallel() && n * C >= (1 << 16))
    for (int64_t r = 0; r < n; ++r) {
      const float* s = src + (r / rows) * bs + (r % rows) * ld;
      for (int64_t c = 0; c < C; ++c) dst[r * C + c] = rounded_to_bf16(s[c]);
    }
  }
};

#if !defined(__aarch64__)
struct TileKernel {
  int64_t (*tile_queries)();
  int64_t (*workspace)(int64_t dh);
  void (*tile)(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work, bool bf16);
};

// Blocked kernel: units of (batch, head, query tile), each thread with its own workspace.
void attention_blocked(const AttentionArgs& a, const TileKernel& kern, bool bf16) {
  const int64_t kTile = kern.tile_queries();
  const int64_t tiles = (a.lq + kTile - 1) / kTile;
  const int64_t units = a.batch * a.heads * tiles;
  const bool prefetch = a.lq <= kTile && a.lk <= kTile;  // short sequences: latency-bound without it
  const bool par = !omp_in_parallel() && units > 1 && a.lq * a.lk * a.dh * a.batch * a.heads >= (1 << 16);
#pragma omp parallel if (par)
  {
    const std::shared_ptr<float[]> work = alloc_floats(static_cast<size_t>(kern.workspace(a.dh)));
    // Short units run in chunks so that the prefetched next unit is usually this thread's own.
    const int64_t chunk = prefetch ? 16 : 1;
#pragma omp for schedule(dynamic, chunk)
    for (int64_t u = 0; u < units; ++u) {
      const int64_t t = u % tiles, h = (u / tiles) % a.heads, b = u / (tiles * a.heads);
      const int64_t q0 = t * kTile;
      if (prefetch && u + 1 < units) {  // single tile per (b, h): the next unit is the next head or batch
        const int64_t hn = (u + 1) % a.heads, bn = (u + 1) / a.heads;
        avx2::prefetch_unit(a, bn, hn, 0, a.lq);
      }
      kern.tile(a, b, h, q0, std::min(kTile, a.lq - q0), work.get(), bf16);
    }
  }
}

// Precision::Bf16 on AVX512-BF16: every (batch, head)'s keys and values converted once, then its query tiles. With
// one tile per (batch, head) (short sequences: temporal attention) each unit converts its own, and prefetches the
// next unit's rows as attention_blocked does.
void attention_avx512_bf16(const AttentionArgs& a) {
  const int64_t kTile = avx512::attention_tile_queries();
  const int64_t tiles = (a.lq + kTile - 1) / kTile, nbh = a.batch * a.heads, units = nbh * tiles;
  const int64_t slots = avx512::attention_bf16_operand_slots(a.lk, a.dh);
  const bool shared = tiles > 1, prefetch = a.lq <= kTile && a.lk <= kTile;
  thread_local AlignedScratch buf;
  uint32_t* const all_ops = shared ? reinterpret_cast<uint32_t*>(buf.get(size_t(nbh * slots))) : nullptr;
  const bool par = !omp_in_parallel() && units > 1 && a.lq * a.lk * a.dh * nbh >= (1 << 16);
#pragma omp parallel if (par)
  {
    const std::shared_ptr<float[]> work =
        alloc_floats(size_t(avx512::attention_bf16_workspace(a.dh) + (shared ? 0 : slots)));
    uint32_t* const own_ops = reinterpret_cast<uint32_t*>(work.get() + avx512::attention_bf16_workspace(a.dh));
    if (shared) {
#pragma omp for schedule(static)
      for (int64_t bh = 0; bh < nbh; ++bh)
        avx512::attention_bf16_prepare(a, bh / a.heads, bh % a.heads, all_ops + bh * slots);
    }
#pragma omp for schedule(dynamic, prefetch ? 16 : 1)
    for (int64_t u = 0; u < units; ++u) {
      const int64_t t = u % tiles, bh = u / tiles, b = bh / a.heads, h = bh % a.heads, q0 = t * kTile;
      if (prefetch && u + 1 < units) avx2::prefetch_unit(a, (u + 1) / a.heads, (u + 1) % a.heads, 0, a.lq);
      uint32_t* ops = shared ? all_ops + bh * slots : own_ops;
      if (!shared) avx512::attention_bf16_prepare(a, b, h, ops);
      avx512::attention_tile_bf16(a, ops, b, h, q0, std::min(kTile, a.lq - q0), work.get());
    }
  }
}
#endif

}  // namespace

void set_attention_bf16_native(bool allowed) { bf16_native_allowed = allowed; }

void attention(const AttentionArgs& a) {
  // Q K^T and P V: 4 dh flop per (query, key) pair; a causal query i sees i + 1 keys.
  const double pairs = a.causal ? 0.5 * double(a.lq) * double(a.lq + 1) : double(a.lq) * double(a.lk);
  const KernelTimer timer(4.0 * double(a.batch * a.heads * a.dh) * pairs, [&] {
    return "attention " + std::to_string(a.batch) + "x" + std::to_string(a.heads) + " heads lq " +
           std::to_string(a.lq) + " lk " + std::to_string(a.lk) + " dh " + std::to_string(a.dh) +
           (a.causal ? " causal" : "");
  });
  EGOPD_CHECK(a.lq > 0 && a.lk > 0 && a.dh > 0, "attention: empty shape");
  EGOPD_CHECK(!a.causal || a.lq == a.lk, "attention: causal mask needs lq == lk");
  const bool bf16 = precision() == Precision::Bf16;
#if !defined(__aarch64__)
  if (bf16 && kernel_path() == KernelPath::Avx512 && cpu_info().avx512_bf16 && bf16_native_allowed)
    return attention_avx512_bf16(a);
#endif
  // Emulated Precision::Bf16: the kernels below on rounded copies of q, k and v.
  const std::optional<RoundedOperands> rounded = bf16 ? std::optional<RoundedOperands>(a) : std::nullopt;
  const AttentionArgs& x = bf16 ? rounded->rounded : a;
#if defined(__aarch64__)
  const auto row_fn = bf16 ? attend_row_bf16 : use_simd() ? neon::attend_row : attend_row;
#else
  if (kernel_path() == KernelPath::Avx512)
    return attention_blocked(
        x, {avx512::attention_tile_queries, avx512::attention_tile_workspace, avx512::attention_tile}, bf16);
  if (use_simd())
    return attention_blocked(x, {avx2::attention_tile_queries, avx2::attention_tile_workspace, avx2::attention_tile},
                             bf16);
  const auto row_fn = bf16 ? attend_row_bf16 : attend_row;
#endif
  const int64_t units = x.batch * x.heads * x.lq;
  const bool par = !omp_in_parallel() && units * x.lk * x.dh >= (1 << 16);
#pragma omp parallel if (par)
  {
    std::vector<float> scores(x.lk);  // one row of probabilities: lk floats per thread
#pragma omp for schedule(static)
    for (int64_t u = 0; u < units; ++u) {
      const int64_t i = u % x.lq, h = (u / x.lq) % x.heads, b = u / (x.lq * x.heads);
      const int64_t off = h * x.dh;
      const int64_t nk = x.causal ? i + 1 : x.lk;
      row_fn(x.q + b * x.q_bs + i * x.q_ld + off, x.k + b * x.k_bs + off, x.k_ld, x.v + b * x.v_bs + off,
                 x.v_ld, nk, x.dh, x.scale, scores.data(), x.out + b * x.out_bs + i * x.out_ld + off);
    }
  }
}

}  // namespace egopd
