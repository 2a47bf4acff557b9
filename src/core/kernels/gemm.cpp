// SGEMM driver: Goto/BLIS blocking (NC columns x KC depth B panels shared by the team, MC x KC A blocks per
// thread, MR x NR micro-tiles), OpenMP across M blocks (or across N panels when M is small), epilogue fused into
// the micro-kernel store of the last K pass.
#include "core/kernels/gemm.h"

#include <omp.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <memory>
#include <cstdlib>
#include <string>
#include <type_traits>
#include <vector>

#include "core/error.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/kernel_profile.h"
#include "core/memory.h"
#include "core/threading.h"

namespace egopd {

float apply_act(Act act, float x) {
  switch (act) {
    case Act::None: return x;
    case Act::SiLU: return x / (1.0f + std::exp(-x));
    case Act::GELU: return 0.5f * x * (1.0f + std::erf(x * 0.70710678118654752f));
    case Act::QuickGELU: return x / (1.0f + std::exp(-1.702f * x));
  }
  return x;
}

namespace {
Precision g_precision = Precision::Fp32;
}

const char* precision_name(Precision p) {
  switch (p) {
    case Precision::Bf16: return "bf16";
    case Precision::Int8: return "int8";
    default: return "fp32";
  }
}

bool parse_precision(const char* name, Precision* out) {
  for (Precision p : {Precision::Fp32, Precision::Bf16, Precision::Int8})
    if (std::string(name) == precision_name(p)) return *out = p, true;
  return false;
}

Precision precision() { return g_precision; }
void set_precision(Precision p) { g_precision = p; }
bool bf16_native() { return gemm_detail::gemm_path().micro_bf16 != nullptr; }
const char* int8_kernel() { return gemm_detail::gemm_path().i8_kernel; }
int int8_b_levels() { return gemm_detail::gemm_path().i8_b_levels; }

namespace gemm_detail {

void round_to_bf16(float* p, int64_t n) {
  for (int64_t i = 0; i < n; ++i) p[i] = rounded_to_bf16(p[i]);
}

namespace {

constexpr int64_t kInt8GroupsPerPass = 4;  // int8 B micro-panel of 4 x 512 x 32 bytes: 64 KiB, in L2
// Bytes of an int8 B block (16 MiB: the U-Net ran ~5% faster than with 2 MiB on the AMD EPYC "Turin-like" CPU);
// EGOPD_GEMM_I8_BLOCK_MB overrides it for tuning experiments.
const int64_t kInt8BBlockBytes = [] {
  const char* e = std::getenv("EGOPD_GEMM_I8_BLOCK_MB");
  return int64_t(e ? std::atoi(e) : 16) << 20;
}();

thread_local AlignedScratch tl_pack;  // the calling thread's; team threads get slices (no allocation inside a region)

int64_t ceil_div(int64_t a, int64_t b) { return (a + b - 1) / b; }

// The last step of the two detours below: each segment's rows of C take (or, with ep.accumulate, add) act of a
// temporary's rows; row i of segment s is at tmp + s * seg_offset + i * row_stride.
void write_back(const GemmJob& job, const float* tmp, int64_t row_stride, int64_t seg_offset, Act act) {
  for (int64_t s = 0; s < job.segments; ++s)
    for (int64_t i = 0; i < job.M; ++i) {
      const float* src = tmp + s * seg_offset + i * row_stride;
      float* dst = job.c + s * job.c_seg_stride + i * job.ldc;
      if (job.ep.accumulate)
        for (int64_t j = 0; j < job.seg_cols; ++j) dst[j] += apply_act(act, src[j]);
      else if (act == Act::None)
        std::copy_n(src, job.seg_cols, dst);
      else
        for (int64_t j = 0; j < job.seg_cols; ++j) dst[j] = apply_act(act, src[j]);
    }
}

// accumulate + activation over several K passes: the activation needs the full sum, so compute it into a
// temporary first (rare: residual adds carry no activation in the models).
void run_gemm_via_temp(const GemmJob& job) {
  const int64_t seg_elems = job.M * job.seg_cols;
  std::vector<float> tmp(size_t(job.segments * seg_elems));
  GemmJob t = job;
  t.c = tmp.data();
  t.ldc = job.seg_cols;
  t.c_seg_stride = seg_elems;
  t.ep.act = Act::None;
  t.ep.accumulate = false;
  run_gemm(t);
  write_back(job, tmp.data(), job.seg_cols, seg_elems, job.ep.act);
}

// Segments narrower than a B panel (the U-Net's 4x4 frames: 16 pixels against avx512's 32 columns) leave most of
// every panel zero. Their columns are packed side by side instead, as one segment, into a temporary C
// [M, segments * seg_cols] that is then copied (or added) to each segment's place.
struct MergedSegmentsB : BSource {
  const BSource* src;
  int64_t seg_cols;
  void pack(const GemmPath& path, int64_t, int64_t k0, int64_t kc, int64_t n0, int nr, float* dst) const override {
    thread_local AlignedScratch part_buf;
    const int NR = path.nr;
    float* const part = part_buf.get(size_t(kc * NR));
    for (int j0 = 0; j0 < nr;) {  // one run of columns per segment
      const int64_t n = n0 + j0, seg = n / seg_cols, c0 = n % seg_cols;
      const int len = int(std::min<int64_t>(nr - j0, seg_cols - c0));
      src->pack(path, seg, k0, kc, c0, len, part);
      for (int64_t k = 0; k < kc; ++k) std::copy_n(part + k * NR, len, dst + k * NR + j0);
      j0 += len;
    }
    if (nr < NR)
      for (int64_t k = 0; k < kc; ++k) std::fill(dst + k * NR + nr, dst + (k + 1) * NR, 0.0f);
  }
};

bool merge_segments(const GemmJob& job, int NR) {
  if (job.segments < 2 || (job.ep.bias && !job.ep.bias_per_row)) return false;  // a column bias indexes seg_cols
  const int64_t separate = job.segments * ceil_div(job.seg_cols, NR);
  return ceil_div(job.segments * job.seg_cols, NR) * 5 < separate * 4;  // saves a fifth of the panels or more
}

void run_gemm_merged(const GemmJob& job) {
  const int64_t cols = job.segments * job.seg_cols;
  thread_local AlignedScratch c_buf;
  float* const tmp = c_buf.get(size_t(job.M * cols));
  MergedSegmentsB b;
  b.src = job.b;
  b.seg_cols = job.seg_cols;
  GemmJob t = job;
  t.segments = 1;
  t.seg_cols = cols;
  t.b = &b;
  t.c = tmp;
  t.ldc = cols;
  t.c_seg_stride = 0;
  t.ep.accumulate = false;
  run_gemm(t);  // tmp [M, segments * seg_cols] = act(A B + bias)
  write_back(job, tmp, cols, job.seg_cols, Act::None);
}

// GEGLU's B: logical panel p is value panel p / 2 (even p) or gate panel p / 2 (odd p) of W's columns [value D | gate
// D], D a multiple of NR, so that each pair of neighbouring panels holds the value and gate columns of one output tile.
struct GluPairsB : BSource {
  const BSource* src;
  int64_t d;
  int64_t column(int64_t n0, int NR) const { return (n0 / NR) % 2 * d + n0 / NR / 2 * NR; }
  void pack(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, float* dst) const override {
    src->pack(path, seg, k0, kc, column(n0, path.nr), nr, dst);
  }
  void pack_bf16_pairs(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                       float* dst) const override {
    src->pack_bf16_pairs(path, seg, k0, kc, column(n0, path.nr), nr, dst);
  }
  void pack_i8(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, int64_t group,
               float* dst, float* floats) const override {
    src->pack_i8(path, seg, k0, kc, column(n0, path.nr), nr, group, dst, floats);
  }
};

// GEGLU where pairs of panels cannot serve (several K passes: the tile pairs need the whole sum; panels that do not
// divide D): the plain product [value | gate] into the caller's scratch, then GEGLU of it.
void run_geglu_via_scratch(const GemmJob& job) {
  if (!job.glu_scratch) throw Error("gemm_geglu: this product needs its [M, 2D] scratch (gemm_geglu_needs_scratch)");
  GemmJob t = job;
  t.b = static_cast<const GluPairsB*>(job.b)->src;
  t.c = job.glu_scratch;
  t.ldc = job.seg_cols;
  t.glu_out = nullptr;
  run_gemm(t);
  geglu(job.glu_scratch, job.M, job.seg_cols / 2, job.glu_out, job.glu_ld);
}

// The K blocking of a product on `path` in the current precision: the int8 quantisation group (0 otherwise), the
// depth of a K pass and the number of passes.
struct KPasses {
  int64_t i8_group, kc_blk, npc;
};
KPasses k_passes(const GemmPath& path, int64_t K) {
  const bool int8 = precision() == Precision::Int8 && K > 0;
  // Int8: K in balanced quantisation groups of at most kInt8Block (gemm.h), a K pass of up to kInt8GroupsPerPass
  // whole groups (the micro-kernel sums the groups of a pass in registers, so C is read and written once per pass).
  const int64_t i8_group = int8 ? int8_group(K) : 0;
  // Bf16 pairs take half the bytes of float32: twice the depth per K pass fills the same cache, and C is read and
  // written half as often.
  const bool bf16_pairs = precision() == Precision::Bf16 && path.micro_bf16;
  const int64_t kc_max = bf16_pairs ? 2 * path.kc : path.kc;
  const int64_t kc_blk = int8 ? i8_group * std::min(kInt8GroupsPerPass, ceil_div(K, i8_group))
                              : K > 0 ? ceil_div(K, ceil_div(K, kc_max)) : 0;
  return {i8_group, kc_blk, kc_blk > 0 ? ceil_div(K, kc_blk) : 1};
}

// Whether a GEGLU of width d and depth K goes through the scratch (run_geglu_via_scratch) on `path`.
bool glu_needs_scratch(const GemmPath& path, int64_t d, int64_t K) {
  return d % path.nr != 0 || k_passes(path, K).npc > 1;
}

}  // namespace

void run_gemm(const GemmJob& job) {
  const int64_t M = job.M, K = job.K;
  if (M <= 0 || job.segments <= 0 || job.seg_cols <= 0) return;
  const GemmPath& path = gemm_path();
  const int MR = path.mr, NR = path.nr;
  if (merge_segments(job, NR)) return run_gemm_merged(job);
  const bool int8 = precision() == Precision::Int8 && K > 0;
  const bool bf16 = precision() == Precision::Bf16, bf16_pairs = bf16 && path.micro_bf16;
  const KPasses passes = k_passes(path, K);  // plain names below (OpenMP regions take no structured bindings)
  const int64_t i8_group = passes.i8_group, kc_blk = passes.kc_blk, npc = passes.npc;
  const int64_t kMcMax = int8 ? path.mc_i8 : path.a_block_rows(kc_blk);
  // Floats between consecutive packed panels of one lane (per MR rows / NR columns): an int8 panel is written over
  // its float32 panel and ends in its lanes' scales and sums, which need a few more rows when kc is tiny.
  const int64_t kc_slot = int8 ? i8_panel_rows(kc_blk) : kc_blk;
  if (job.ep.accumulate && job.ep.act != Act::None && npc > 1) return run_gemm_via_temp(job);
  const bool glu = job.glu_out != nullptr;
  if (glu && glu_needs_scratch(path, job.seg_cols / 2, K)) return run_geglu_via_scratch(job);
  // Int8: B micro-panels are packed in float32 into a buffer of the thread's and quantised into compact slots (a
  // quarter of the bytes), and a B block spans about kInt8BBlockBytes: several times the columns of a float32
  // block, so A (packed and quantised once per column block and thread) is repacked that much less often.
  const int64_t b_panel_floats =
      int8 ? ceil_div(kc_blk, i8_group) * i8_region(NR, i8_group) : kc_slot * NR;
  const int64_t kNcMax =
      int8 ? std::max<int64_t>(path.nc, kInt8BBlockBytes / (b_panel_floats * 4) * NR) : path.nc;

  // Bf16: every panel is packed as bfloat16 pairs (native) or rounded right after packing (emulated), so A is
  // always packed.
  // Int8: every packed panel is quantised (see GemmPath::quantize_a_i8), so A is always packed too.
  const MicroKernel uk = int8 ? path.micro_i8 : bf16_pairs ? path.micro_bf16 : path.micro;
  const int64_t panels_per_seg = ceil_div(job.seg_cols, NR);
  const int64_t npanels = job.segments * panels_per_seg;
  const int64_t unit = glu ? 2 : 1;  // panels handed out together: GEGLU's pairs never straddle blocks or threads
  const int64_t jc_panels = unit * ceil_div(ceil_div(npanels, unit), ceil_div(npanels * NR, kNcMax));
  const int64_t njc = ceil_div(npanels, jc_panels);
  const int64_t mpanels = ceil_div(M, MR);

  const double flops = 2.0 * double(M) * double(job.segments * job.seg_cols) * double(K);
  int threads = omp_in_parallel() ? 1 : num_threads();
  if (flops < kSerialFlops) threads = 1;
  // Split N across threads whenever each thread gets a few column panels: every thread packs its own B panels and
  // reuses them over all rows, with no barrier and no cache lines shared between cores (measured faster than
  // splitting M on every float32 U-Net shape, linear and convolution). Splitting M (shared B blocks, one barrier
  // per block, dynamic row chunks) is for narrow outputs, and for bf16 and int8 outputs of up to 160 / 320
  // columns per thread: there, splitting N, every thread would pack (and round or quantise) all of A for its few
  // columns (AMD EPYC Zen 5 class, 2 threads, bench gemm: N = 320 +15% bf16, +30% int8; N = 640 int8 +15-24%,
  // bf16 -7 to +3%; N = 1280 slower both ways).
  // A read in place streams MR rows lda apart. When that stride is a multiple of 4 KiB (the span of the L1's sets)
  // all of them fall into one set, more lines than it has ways: pack A instead (K = 5120, 20 KiB rows: 145 -> 195
  // GFLOP/s on AVX-512, 142-152 -> 163 on AVX2; AMD EPYC Zen 4, 2 threads, 1024 x 1280 x 5120).
  const bool a_rows_alias = job.a->direct != nullptr && job.a->lda * int64_t(sizeof(float)) % 4096 == 0;
  const bool direct_a = job.a->direct != nullptr && path.a_in_place && !bf16 && !int8 && !a_rows_alias;
  const int64_t cols_per_thread = npanels * NR / threads;
  const bool a_packing_heavy = (bf16 && cols_per_thread <= 160) || (int8 && cols_per_thread <= 320);
  const bool split_m = (npanels < int64_t(threads) * 4 || a_packing_heavy) && mpanels >= npanels;
  threads = int(std::min<int64_t>(threads, split_m ? mpanels : npanels));

  // Splitting M, panel p of a B block sits at slot p - p_begin (shared); splitting N, each thread packs and reads
  // only its own panels, in its own slots (threads run unsynchronised, so the slots must not move with kc or
  // with the size of the column block).
  const int64_t b_block = b_panel_floats * (jc_panels + (split_m ? 0 : unit * threads));  // floats of one B block
  const int64_t b_float_panel = int8 ? kc_slot * NR : 0;  // int8: one float32 B micro-panel per thread
  const bool double_buffer = split_m && threads > 1 && njc * npc > 1;
  const int64_t a_slice = direct_a ? 0 : (kMcMax * kc_slot + 15) / 16 * 16;  // floats of one thread's A block
  const int64_t b_floats = b_block * (double_buffer ? 2 : 1);
  float* const scratch = tl_pack.get(size_t(b_floats + int64_t(threads) * (a_slice + b_float_panel)) + 16);
  float* const b_shared = scratch;
  const Epilogue& ep = job.ep;
  // Row chunks handed out dynamically (a thread slowed down by anything else on the machine takes fewer): up to
  // 4 per thread but no fewer than ~96 rows (each B micro-panel is reused over a chunk's rows), at most one
  // L2-sized A block. One counter per (jc, pc) iteration.
  int64_t chunk_rows = kMcMax;
  if (split_m) {
    const int64_t per_thread = ceil_div(M, threads);
    const int64_t chunks = std::max(ceil_div(per_thread, kMcMax), std::clamp<int64_t>(per_thread / 96, 1, 4));
    chunk_rows = ceil_div(ceil_div(per_thread, chunks), MR) * MR;
  }
  const int64_t nchunks = ceil_div(M, chunk_rows);
  std::unique_ptr<std::atomic<int64_t>[]> next_chunk(new std::atomic<int64_t>[size_t(njc * npc)]);
  for (int64_t i = 0; i < njc * npc; ++i) next_chunk[i].store(0, std::memory_order_relaxed);

#pragma omp parallel num_threads(threads) if (threads > 1)
  {
    const int nth = omp_get_num_threads(), tid = omp_get_thread_num();
    float* const a_pack = direct_a ? nullptr : scratch + b_floats + tid * a_slice;
    float* const b_float = scratch + b_floats + threads * a_slice + tid * b_float_panel;
    int64_t iter = 0;
    for (int64_t jc = 0; jc < njc; ++jc) {
      const int64_t p_begin = jc * jc_panels, p_end = std::min(npanels, p_begin + jc_panels);
      const int64_t np = p_end - p_begin;
      // Panels this thread packs, and panels it multiplies (all of them when splitting M).
      // GEGLU: whole pairs per thread.
      const int64_t units = ceil_div(np, unit);
      const int64_t pk_lo = p_begin + unit * (units * tid / nth);
      const int64_t pk_hi = std::min(p_end, p_begin + unit * (units * (tid + 1) / nth));
      const int64_t pm_lo = split_m ? p_begin : pk_lo, pm_hi = split_m ? p_end : pk_hi;
      // From the full block's width, not this block's: the slots must not move between blocks either.
      const int64_t own_slots = unit * ceil_div(jc_panels / unit, nth);  // nth * own_slots <= jc_panels + unit * nth
      const auto panel_slot = [&](int64_t p) { return split_m ? p - p_begin : p - pk_lo + tid * own_slots; };
      for (int64_t pc = 0; pc < npc; ++pc, ++iter) {
        const int64_t k0 = pc * kc_blk, kc = std::min(kc_blk, K - k0);
        float* b_pack = b_shared + (double_buffer ? (iter & 1) * b_block : 0);
        if (split_m && nth > 1 && !double_buffer && iter > 0) {
#pragma omp barrier
        }
        for (int64_t p = pk_lo; p < pk_hi; ++p) {
          const int64_t seg = p / panels_per_seg, n0 = (p % panels_per_seg) * NR;
          const int nr = int(std::min<int64_t>(NR, job.seg_cols - n0));
          float* panel = b_pack + panel_slot(p) * b_panel_floats;
          if (bf16_pairs) {
            job.b->pack_bf16_pairs(path, seg, k0, kc, n0, nr, panel);
            continue;
          }
          if (int8) {
            job.b->pack_i8(path, seg, k0, kc, n0, nr, i8_group, panel, b_float);
            continue;
          }
          job.b->pack(path, seg, k0, kc, n0, nr, panel);
          if (bf16) round_to_bf16(panel, kc * NR);
        }
        if (split_m && nth > 1) {
#pragma omp barrier
        }
        const bool last = pc == npc - 1;
        TileEpilogue te;
        te.act = last ? ep.act : Act::None;
        te.load_c = pc > 0 || (ep.accumulate && ep.act == Act::None);
        te.add_after = ep.accumulate && ep.act != Act::None;
        te.i8_group = i8_group;
        const float* bias_row = last && ep.bias && ep.bias_per_row ? ep.bias : nullptr;
        const float* bias_col = last && ep.bias && !ep.bias_per_row ? ep.bias : nullptr;
        // One tile: rows i .. i + mr - 1 (ir into the chunk's packed A) times a packed B panel, into c.
        const auto multiply = [&](int64_t i, int64_t ir, int mr, const float* bp, float* c, int64_t ldc, int nr,
                                  const TileEpilogue& t) {
          if (direct_a)
            uk(kc, job.a->direct + i * job.a->lda + k0, job.a->lda, 1, bp, c, ldc, mr, nr, t);
          else
            uk(kc, a_pack + ir * kc_slot, 1, MR, bp, c, ldc, mr, nr, t);
        };
        // GEGLU: each pair's value and gate tiles into scratch (no C), then combined into glu_out.
        const auto glu_pairs = [&](int64_t p_lo, int64_t p_hi, int64_t ic, int64_t mc, TileEpilogue t,
                                   const float* bias) {
          alignas(64) float tiles[2][kMaxTile];  // value, gate
          const auto& pairs = static_cast<const GluPairsB&>(*job.b);
          for (int64_t p = p_lo; p < p_hi; p += 2)
            for (int64_t ir = 0; ir < mc; ir += MR) {
              const int64_t i = ic + ir;
              const int mr = int(std::min<int64_t>(MR, mc - ir));
              float* const out = job.glu_out + i * job.glu_ld + p / 2 * NR;  // the pair's GEGLU tile
              // Its rows are written right after the two products: fetch their lines meanwhile (the
              // micro-kernel's own prefetch covers only its scratch tiles).
              for (int r = 0; r < mr; ++r)
                for (int64_t j = 0; j < NR; j += 16) __builtin_prefetch(out + r * job.glu_ld + j, 1, 3);
              for (int h = 0; h < 2; ++h) {
                t.bias_col = bias ? bias + pairs.column((p + h) * NR, NR) : nullptr;
                multiply(i, ir, mr, b_pack + panel_slot(p + h) * b_panel_floats, tiles[h], NR, NR, t);
              }
              // Row by row straight into glu_out, whose lines the prefetch above has brought in.
              for (int r = 0; r < mr; ++r)
                geglu_row(tiles[0] + r * NR, tiles[1] + r * NR, NR, out + r * job.glu_ld);
            }
        };
        // split_m: take row chunks until none is left; otherwise this thread's panels times all rows.
        for (int64_t chunk = split_m ? next_chunk[iter].fetch_add(1) : 0; chunk < nchunks;
             chunk = split_m ? next_chunk[iter].fetch_add(1) : chunk + 1) {
          const int64_t ic = chunk * chunk_rows, mc = std::min(chunk_rows, M - ic);
          if (!direct_a)
            for (int64_t ir = 0; ir < mc; ir += MR) {
              float* panel = a_pack + ir * kc_slot;
              const int mr = int(std::min<int64_t>(MR, mc - ir));
              if (bf16_pairs) {
                job.a->pack_bf16_pairs(path, ic + ir, mr, k0, kc, panel);
                continue;
              }
              if (int8) {
                job.a->pack_i8(path, ic + ir, mr, k0, kc, i8_group, panel);
                continue;
              }
              job.a->pack(path, ic + ir, mr, k0, kc, panel);
              if (bf16) round_to_bf16(panel, kc * MR);
            }
          if (glu) {
            glu_pairs(pm_lo, pm_hi, ic, mc, te, bias_col);
            continue;
          }
          for (int64_t p = pm_lo; p < pm_hi; ++p) {
            const int64_t seg = p / panels_per_seg, n0 = (p % panels_per_seg) * NR;
            const int nr = int(std::min<int64_t>(NR, job.seg_cols - n0));
            const float* bp = b_pack + panel_slot(p) * b_panel_floats;
            float* cp = job.c + seg * job.c_seg_stride + n0;
            te.bias_col = bias_col ? bias_col + n0 : nullptr;
            for (int64_t ir = 0; ir < mc; ir += MR) {
              const int64_t i = ic + ir;
              const int mr = int(std::min<int64_t>(MR, mc - ir));
              te.bias_row = bias_row ? bias_row + i : nullptr;
              multiply(i, ir, mr, bp, cp + i * job.ldc, job.ldc, nr, te);
            }
          }
        }
      }
    }
  }
}

OperandA::OperandA(const Operand& o) : op(o) {
  if (o.dtype == DType::F32 && !o.trans) {
    direct = static_cast<const float*>(o.data);
    lda = o.ld;
  }
}

namespace {
// The panel of `lanes` lanes (A's rows or B's columns) from lane0 and kc depths from k0 of `op` (from element
// seg_off), with a PackA or PackB; lane_major: element (lane, k) at lane * ld + k, else at k * ld + lane.
template <class Packer>
void pack_operand(Packer pack, const Operand& op, int64_t seg_off, bool lane_major, int64_t lane0, int lanes,
                  int64_t k0, int64_t kc, float* dst) {
  const int64_t off = seg_off + (lane_major ? lane0 * op.ld + k0 : k0 * op.ld + lane0);
  const void* p = op.element(off);
  const float* scale = op.scale ? op.scale + lane0 : nullptr;
  if constexpr (std::is_same_v<Packer, PackA>) pack(p, op.dtype, op.ld, op.trans, scale, lanes, kc, dst);
  else pack(p, op.dtype, op.ld, op.trans, scale, kc, lanes, dst);
}
}  // namespace

// A(m, k) = data[m*ld + k], or data[k*ld + m] when trans.
void OperandA::pack(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const {
  pack_operand(path.pack_a, op, 0, !op.trans, m0, mr, k0, kc, dst);
}
void OperandA::pack_bf16_pairs(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, float* dst) const {
  if (!path.pack_a_bf16) return ASource::pack_bf16_pairs(path, m0, mr, k0, kc, dst);
  pack_operand(path.pack_a_bf16, op, 0, !op.trans, m0, mr, k0, kc, dst);
}

void OperandA::pack_i8(const GemmPath& path, int64_t m0, int mr, int64_t k0, int64_t kc, int64_t group,
                       float* dst) const {
  if (!direct || !path.pack_a_i8) return ASource::pack_i8(path, m0, mr, k0, kc, group, dst);
  path.pack_a_i8(direct + m0 * lda + k0, lda, mr, kc, group, dst);
}

// B(k, n) = data[k*ld + n], or data[n*ld + k] when trans.
void OperandB::pack(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                    float* dst) const {
  pack_operand(path.pack_b, op, seg * seg_stride, op.trans, n0, nr, k0, kc, dst);
}
void OperandB::pack_bf16_pairs(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr,
                               float* dst) const {
  if (!path.pack_b_bf16) return BSource::pack_bf16_pairs(path, seg, k0, kc, n0, nr, dst);
  pack_operand(path.pack_b_bf16, op, seg * seg_stride, op.trans, n0, nr, k0, kc, dst);
}
void OperandB::pack_i8(const GemmPath& path, int64_t seg, int64_t k0, int64_t kc, int64_t n0, int nr, int64_t group,
                       float* dst, float* floats) const {
  if (!path.pack_b_i8 || !op.trans || (op.dtype != DType::F32 && op.dtype != DType::F16))
    return BSource::pack_i8(path, seg, k0, kc, n0, nr, group, dst, floats);
  path.pack_b_i8(op.element(seg * seg_stride + n0 * op.ld + k0), op.dtype, op.ld, nr, kc, group, dst);
}

}  // namespace gemm_detail

static void check_operand(const Operand& op, const char* name) {
  if (op.dtype != DType::F32 && op.dtype != DType::F16 && op.dtype != DType::BF16 && op.dtype != DType::I8)
    throw Error(std::string("gemm: operand ") + name + " has unsupported dtype " + dtype_name(op.dtype));
  if (op.dtype == DType::I8 && !op.scale) throw Error(std::string("gemm: I8 operand ") + name + " has no scale");
}

void gemm(int64_t M, int64_t N, int64_t K, const Operand& A, const Operand& B, float* C, int64_t ldc,
          const Epilogue& ep) {
  const KernelTimer timer(2.0 * double(M) * double(N) * double(K), [&] {
    return "gemm " + std::to_string(M) + "x" + std::to_string(N) + "x" + std::to_string(K) +
           (A.trans ? " A^T " : " A ") + dtype_name(A.dtype) + (B.trans ? " B^T " : " B ") + dtype_name(B.dtype);
  });
  if (M <= 0 || N <= 0) return;
  check_operand(A, "A");
  check_operand(B, "B");
  gemm_detail::OperandA a(A);
  gemm_detail::OperandB b(B);
  gemm_detail::GemmJob job;
  job.M = M;
  job.K = K;
  job.seg_cols = N;
  job.a = &a;
  job.b = &b;
  job.c = C;
  job.ldc = ldc;
  job.ep = ep;
  gemm_detail::run_gemm(job);
}

bool gemm_geglu_needs_scratch(int64_t D, int64_t K) {
  return gemm_detail::glu_needs_scratch(gemm_detail::gemm_path(), D, K);
}

void gemm_geglu(int64_t M, int64_t D, int64_t K, const Operand& A, const Operand& B, const float* bias, float* out,
                int64_t ldo, float* scratch) {
  const KernelTimer timer(4.0 * double(M) * double(D) * double(K), [&] {
    return "gemm_geglu " + std::to_string(M) + "x" + std::to_string(2 * D) + "x" + std::to_string(K) +
           (A.trans ? " A^T " : " A ") + dtype_name(A.dtype) + (B.trans ? " B^T " : " B ") + dtype_name(B.dtype);
  });
  if (M <= 0 || D <= 0) return;
  check_operand(A, "A");
  check_operand(B, "B");
  gemm_detail::OperandA a(A);
  gemm_detail::OperandB b(B);
  gemm_detail::GluPairsB pairs;
  pairs.src = &b;
  pairs.d = D;
  gemm_detail::GemmJob job;
  job.M = M;
  job.K = K;
  job.seg_cols = 2 * D;
  job.a = &a;
  job.b = &pairs;
  job.ep.bias = bias;
  job.glu_out = out;
  job.glu_ld = ldo;
  job.glu_scratch = scratch;
  gemm_detail::run_gemm(job);
}

}  // namespace egopd
