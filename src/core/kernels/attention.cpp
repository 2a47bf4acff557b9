#include "core/kernels/attention.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/kernel_profile.h"
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
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work);
void prefetch_unit(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq);
}  // namespace avx2
namespace avx512 {
int64_t attention_tile_queries();
int64_t attention_tile_workspace(int64_t dh);
void attention_tile(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work);
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

// One query row of one head against its nk keys: scores into p [nk], stable softmax, then P.V into out.
void attend_row(const float* q, const float* k, int64_t k_ld, const float* v, int64_t v_ld, int64_t nk, int64_t dh,
                float scale, float* p, float* out) {
  float mx = -INFINITY;
  for (int64_t j = 0; j < nk; ++j) {
    p[j] = dot(q, k + j * k_ld, dh) * scale;
    mx = std::max(mx, p[j]);
  }
  float sum = 0.0f;
  for (int64_t j = 0; j < nk; ++j) sum += (p[j] = std::exp(p[j] - mx));
  std::fill(out, out + dh, 0.0f);
  for (int64_t j = 0; j < nk; ++j) {
    const float* vr = v + j * v_ld;
    const float pj = p[j];
    for (int64_t d = 0; d < dh; ++d) out[d] += pj * vr[d];
  }
  const float inv = 1.0f / sum;
  for (int64_t d = 0; d < dh; ++d) out[d] *= inv;
}

#if !defined(__aarch64__)
struct TileKernel {
  int64_t (*tile_queries)();
  int64_t (*workspace)(int64_t dh);
  void (*tile)(const AttentionArgs& a, int64_t b, int64_t h, int64_t q0, int64_t nq, float* work);
};

// Blocked kernel: units of (batch, head, query tile), each thread with its own workspace.
void attention_blocked(const AttentionArgs& a, const TileKernel& kern) {
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
      kern.tile(a, b, h, q0, std::min(kTile, a.lq - q0), work.get());
    }
  }
}
#endif

}  // namespace

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
#if defined(__aarch64__)
  const auto row_fn = use_simd() ? neon::attend_row : attend_row;
#else
  if (kernel_path() == KernelPath::Avx512)
    return attention_blocked(a, {avx512::attention_tile_queries, avx512::attention_tile_workspace, avx512::attention_tile});
  if (use_simd())
    return attention_blocked(a, {avx2::attention_tile_queries, avx2::attention_tile_workspace, avx2::attention_tile});
  const auto row_fn = attend_row;
#endif
  const int64_t units = a.batch * a.heads * a.lq;
  const bool par = !omp_in_parallel() && units * a.lk * a.dh >= (1 << 16);
#pragma omp parallel if (par)
  {
    std::vector<float> scores(a.lk);  // one row of probabilities: lk floats per thread
#pragma omp for schedule(static)
    for (int64_t u = 0; u < units; ++u) {
      const int64_t i = u % a.lq, h = (u / a.lq) % a.heads, b = u / (a.lq * a.heads);
      const int64_t off = h * a.dh;
      const int64_t nk = a.causal ? i + 1 : a.lk;
      row_fn(a.q + b * a.q_bs + i * a.q_ld + off, a.k + b * a.k_bs + off, a.k_ld, a.v + b * a.v_bs + off,
                 a.v_ld, nk, a.dh, a.scale, scores.data(), a.out + b * a.out_bs + i * a.out_ld + off);
    }
  }
}

}  // namespace egopd
