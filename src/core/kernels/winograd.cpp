// Winograd F(m x m, 3x3) driver. For a block of output channels and a block of tiles: filter transform (U, packed
// as the GEMM's A panels), input transform (V, packed as its B panels), alpha^2 GEMMs M_xi = U_xi · V_xi on the
// path's micro-kernel (the transforms write the packed layouts directly, so no packing pass), output transform with
// the conv2d epilogue. One parallel region per call; each phase is a work-shared loop (barrier between phases).
//
// Memory: the transformed filters are recomputed on every call, never kept (a transformed copy of every 3x3 filter
// would be 4x (F(4x4): 36/9) the fp32 weights, 8x the stored F16 ones: several GB for the U-Net). U is blocked over
// output channels to WinogradBudgets::filter bytes, V and M over tiles to ::tiles bytes (all tiles up to
// ::whole_tiles when several blocks of output channels share them); the scratch is the calling thread's, grown on
// demand and kept like the GEMM's packing scratch.
#include "core/kernels/winograd.h"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/error.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"
#include "core/kernels/winograd_transforms.h"
#include "core/memory.h"
#include "core/threading.h"

namespace egopd {

namespace {
int64_t ceil_div(int64_t a, int64_t b) { return (a + b - 1) / b; }
}  // namespace

namespace wino_detail {

WinogradBudgets& winograd_budgets() {
  static WinogradBudgets b;
  return b;
}

namespace {

WinogradBlocking plan_blocking(int64_t K, int64_t cout, int64_t ntiles, int64_t a2, int mr, int64_t L,
                               int64_t filter_budget) {
  const WinogradBudgets& budget = winograd_budgets();
  WinogradBlocking b;
  // Output-channel blocks (rows of U), then tile blocks (columns of V and M), each a whole number of panels.
  b.co = std::max<int64_t>(mr, filter_budget / (a2 * K * 4) / mr * mr);
  b.ncb = ceil_div(cout, b.co);
  b.co = ceil_div(ceil_div(cout, b.ncb), mr) * mr;
  const auto block_tiles = [&] {
    b.tb = std::max(L, std::max(budget.min_block_tiles, budget.tiles / (a2 * (K + b.co) * 4)) / L * L);
    // Several blocks of output channels each need every tile's V: rather than transforming the input again for
    // each, keep all tiles in one block when that fits budget.whole_tiles (U-Net layers of 640 channels on 16x16
    // frames: 2x faster).
    if (b.ncb > 1 && ntiles * a2 * (K + b.co) * 4 <= budget.whole_tiles) b.tb = ceil_div(ntiles, L) * L;
    b.ntb = ceil_div(ntiles, b.tb);
    b.tb = ceil_div(ceil_div(ntiles, b.ntb), L) * L;
  };
  block_tiles();
  // Still several blocks of both: one block of all output channels if its U fits budget.whole_filter (the VAE
  // decoder's 512-channel 64x64 layers: 1.3x faster than transforming each tile block's input three times).
  if (const int64_t all = ceil_div(cout, mr) * mr; b.ncb > 1 && b.ntb > 1 && a2 * K * all * 4 <= budget.whole_filter) {
    b.co = all;
    b.ncb = 1;
    block_tiles();
  }
  // With several blocks of both, one transform is recomputed for every block of the other: V for each block of
  // output channels, or U for each block of tiles. Recompute the smaller: the input transform costs about as much
  // per (tile, input channel) as the filter transform per (output channel, input channel).
  b.tiles_outside = b.ncb > 1 && b.ntb > 1 && b.ntb * cout < b.ncb * ntiles;
  return b;
}

// Where U is transformed anew for each block of output channels (several blocks), each thread keeps to its own rows
// of a block in all three phases, so that U and the products never pass between cores: blocks of a multiple of
// threads x mr rows. A 2-core AMD EPYC Zen 4 host runs its two threads in two modes, one of them slow wherever data
// passes between them; there, 16 frames, float32: 1280 -> 1280 on 8x8 87 -> 55 ms a call, on 16x16 255 -> 205 ms,
// 640 -> 640 on 32x32 265 -> 220 ms; in the fast mode 0.9-1.15x the time (BENCHMARKS.md, forty-sixth session). Of
// the block counts from the plan's to twice it, the one whose blocks pad cout least (the fewest blocks on a tie): the
// rounding of the plan's own blocks may add most of a block (960 -> 640 channels, 108-row blocks: 6 of 120 rows,
// 720 in all, against 9 of 72, 648).
WinogradBlocking with_own_rows(WinogradBlocking b, int64_t cout, int mr, int threads) {
  if (threads <= 1 || b.ncb <= 1) return b;
  const int64_t unit = int64_t(threads) * mr;
  int64_t best = 0;
  for (int64_t blocks = b.ncb; blocks <= 2 * b.ncb; ++blocks) {
    const int64_t co = ceil_div(ceil_div(cout, blocks), unit) * unit;
    if (best == 0 || ceil_div(cout, co) * co < ceil_div(cout, best) * best) best = co;
  }
  b.co = best;
  b.ncb = ceil_div(cout, best);
  b.own_rows = b.ncb > 1;
  return b;
}

}  // namespace

WinogradBlocking winograd_blocking(int64_t cin, int64_t cout, int64_t ntiles, int64_t a2, int mr, int lanes,
                                   int threads) {
  const int64_t K = std::max<int64_t>(cin, 1), L = lanes;
  const WinogradBudgets& budget = winograd_budgets();
  const auto plan = [&](int64_t filter_budget) {
    return with_own_rows(plan_blocking(K, cout, ntiles, a2, mr, L, filter_budget), cout, mr, threads);
  };
  const WinogradBlocking b = plan(budget.filter);
  // The GEMM of one tile position multiplies U's slice (co x K) by V's (tb x K). Where V's slice takes at most 3/4
  // of L2, a block of U within budget.filter_near (4x L2) keeps U's slices near too (U-Net, 16 frames, AMD EPYC Zen
  // 5 class, 1 MiB L2, alternating runs: 1280 channels on 8x8 1.2-1.4x faster, 960->640 on 16x16 1.06-1.3x,
  // 640->1280 on 8x8 1.03-1.2x). Where V's slice alone exceeds that (1920->640 on 16x16), smaller U blocks only
  // re-read V more often (1.1x slower): those keep budget.filter (the early return only skips planning twice).
  const int64_t l2 = cpu_info().l2_bytes(), v_fits = l2 * 3 / 4;
  const int64_t near = std::min(budget.filter, budget.filter_near > 0 ? budget.filter_near : 4 * l2);
  if (b.tb * K * 4 > v_fits) return b;
  const WinogradBlocking n = plan(near);
  return n.tb * K * 4 <= v_fits ? n : b;
}

void apply_act_inplace(Act act, float* v, int64_t n) {
  switch (act) {
    case Act::None: return;
    case Act::SiLU: return silu_inplace(v, n);
    case Act::GELU: return gelu_inplace(v, n);
    case Act::QuickGELU: return quick_gelu_inplace(v, n);
  }
}

const WinogradKernels& winograd_kernels_portable() {
  static const WinogradKernels k = make_winograd_kernels<gemm_detail::kNrPortable, gemm_detail::kMrPortable>();
  return k;
}

const WinogradKernels& winograd_kernels(KernelPath p) {
#if defined(__x86_64__)
  if (p == KernelPath::Avx512) return winograd_kernels_avx512();
  if (p == KernelPath::Avx2) return winograd_kernels_avx2();
#elif defined(__aarch64__)
  if (p == KernelPath::Neon) return winograd_kernels_neon();
#endif
  return winograd_kernels_portable();
}

}  // namespace wino_detail

namespace {

using wino_detail::PanelGeom;


// The calling thread's scratch, 64-byte aligned (the B panels the micro-kernels load must be), grown on demand.
float* thread_scratch(size_t floats) {
  thread_local AlignedScratch buf;
  return buf.get(floats);
}

// The segments of the panel of tiles [g0, g0 + nt) (tile g: frame g / tpf, row-major inside the frame).
PanelGeom panel_geom(int64_t g0, int nt, int64_t tiles_x, int64_t tpf, int64_t h, int64_t w) {
  PanelGeom pg;
  pg.h = h;
  pg.w = w;
  for (int j = 0; j < nt; ++j) {
    const int64_t g = g0 + j, f = g / tpf, r = g % tpf, ty = r / tiles_x, tx = r % tiles_x;
    wino_detail::Segment* s = pg.nseg ? &pg.seg[pg.nseg - 1] : nullptr;
    if (s && s->f == f && s->ty == ty) {
      s->j1 = j + 1;
    } else {
      pg.seg[pg.nseg++] = {f, ty, tx, j, j + 1};
    }
  }
  return pg;
}

}  // namespace

const char* winograd_tile_name(WinogradTile t) { return t == WinogradTile::F4x4 ? "F(4x4,3x3)" : "F(2x2,3x3)"; }

WinogradTile winograd_tile_for(int64_t h, int64_t w) {
  // A 4x4 tile reads a 6x6 patch: on a frame narrower than 8 most of it is padding.
  return std::min(h, w) >= 8 ? WinogradTile::F4x4 : WinogradTile::F2x2;
}

bool winograd_wins(int64_t cin, int64_t cout, int64_t n, int64_t h, int64_t w) {
  // Few channels: the transforms (O(cin + cout) per tile) outweigh the GEMM saving (O(cin * cout) per tile).
  // Frames under 4 pixels: edge tiles are mostly padding. Few pixels in all: the per-call filter transform is not
  // paid back by the GEMM saving per pixel. Measured on 1280 channels, 2 threads of an AMD EPYC (Zen 5 class): F(4x4)
  // on 8x8 frames is even at 8 frames (512 pixels) and wins at 16 (1.7x with one thread). F(2x2) on 4x4 frames: the
  // path's thresholds (GemmPath::winograd_f2_min_pixels), lower in float32 than where bf16 doubles the direct rate;
  // there F(4x4) also keeps to frames of GemmPath::winograd_f4_min_frame_bf16.
  if (cin < 16 || cout < 16 || std::min(h, w) < 4) return false;
  const bool f4 = winograd_tile_for(h, w) == WinogradTile::F4x4;
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  const bool bf16 = precision() == Precision::Bf16;
  if (f4 && bf16 && std::min(h, w) < path.winograd_f4_min_frame_bf16) return false;
  const int64_t f2_min = bf16 ? path.winograd_f2_min_pixels_bf16 : path.winograd_f2_min_pixels;
  return n * h * w >= (f4 ? 512 : f2_min);
}

namespace {

// Precision::Int8's scales: of the input per pixel and group of channels (wino_detail::InputQuant), of the weights
// per output channel and group of its cin * 9 taps (k = c * 9 + t), in the direct convolution's groups (gemm.h's
// int8_group of K = cin * 9), laid out [group][output channel] with the channels padded to a multiple of mr (zeros).
struct Int8Scales {
  std::vector<float> x_inv, x_scale, w_inv, w_scale;
  int64_t x_group = 1, x_groups = 1, w_group = 1, w_ld = 0;
  wino_detail::InputQuant input() const { return {x_inv.data(), x_scale.data(), x_group, x_groups}; }
  // The weights' scales for the lanes of output channels o, o + 1, ...
  wino_detail::TapScales taps(int64_t o) const { return {w_inv.data() + o, w_scale.data() + o, w_group, w_ld}; }
};

// Largest magnitude of the n stored weights from element e0 of `w` (of output channel o), as float32 exactly as the
// packers convert them: NaN if one is NaN. On the stored bits (the magnitudes of IEEE values order as their bits
// without the sign, NaN above inf), so that one plain integer loop serves every dtype; I8: max |q| times the
// channel's scale (a product by a positive scale keeps the order).
float stored_abs_max(const Operand& w, int64_t e0, int64_t n, int64_t o) {
  const auto max_bits = [&](const auto* p, auto mask) {
    decltype(mask) m = 0;
    for (int64_t i = 0; i < n; ++i) m = std::max<decltype(mask)>(m, p[e0 + i] & mask);
    return m;
  };
  switch (w.dtype) {
    case DType::F32: {
      const uint32_t bits = max_bits(static_cast<const uint32_t*>(w.data), uint32_t(0x7fffffff));
      float m;
      std::memcpy(&m, &bits, sizeof m);
      return m;
    }
    case DType::F16: return half_to_float(max_bits(static_cast<const uint16_t*>(w.data), uint16_t(0x7fff)));
    case DType::BF16: return bf16_to_float(max_bits(static_cast<const uint16_t*>(w.data), uint16_t(0x7fff)));
    default: {
      const int8_t* q = static_cast<const int8_t*>(w.data) + e0;
      int m = 0;
      for (int64_t i = 0; i < n; ++i) m = std::max(m, std::abs(int(q[i])));
      return float(m) * w.scale[o];
    }
  }
}

Int8Scales int8_scales(const float* x, int64_t n, int64_t plane, int64_t cin, const Operand& weight, int64_t cout,
                       int mr) {
  Int8Scales s;
  const int64_t group = int8_group(cin), groups = ceil_div(cin, group);
  s.x_group = group;
  s.x_groups = groups;
  s.x_inv.resize(size_t(n * groups * plane));
  s.x_scale.resize(s.x_inv.size());
  const int64_t K = cin * 9;
  s.w_group = int8_group(K);
  const int64_t w_groups = ceil_div(K, s.w_group), panels = ceil_div(cout, mr);
  s.w_ld = panels * mr;
  s.w_inv.assign(size_t(w_groups * s.w_ld), 0.0f);
  s.w_scale.assign(s.w_inv.size(), 0.0f);
  constexpr int64_t kPixels = 1024;  // a run of pixels whose maxima stay in L1
  const int64_t runs = ceil_div(plane, kPixels);
  const int threads = omp_in_parallel() ? 1 : num_threads();
#pragma omp parallel num_threads(threads) if (threads > 1)
  {
#pragma omp for collapse(2) schedule(static) nowait
    for (int64_t fg = 0; fg < n * groups; ++fg)
      for (int64_t r = 0; r < runs; ++r) {
        const int64_t f = fg / groups, c0 = fg % groups * group, c1 = std::min(cin, c0 + group);
        const int64_t p0 = r * kPixels, np = std::min(kPixels, plane - p0);
        float m[kPixels] = {};
        for (int64_t c = c0; c < c1; ++c) {
          const float* xc = x + (f * cin + c) * plane + p0;
          for (int64_t p = 0; p < np; ++p) m[p] = gemm_detail::nan_sticky_max(m[p], std::fabs(xc[p]));
        }
        for (int64_t p = 0; p < np; ++p) {
          s.x_inv[size_t(fg * plane + p0 + p)] = gemm_detail::i8_inverse(m[p]);
          s.x_scale[size_t(fg * plane + p0 + p)] = gemm_detail::i8_scale(m[p]);
        }
      }
    // The weights' groups: runs of their output channel's row of the stored [cout, cin * 9] weight.
#pragma omp for collapse(2) schedule(static)
    for (int64_t o = 0; o < cout; ++o)
      for (int64_t g = 0; g < w_groups; ++g) {
        const int64_t k0 = g * s.w_group;
        const float m = stored_abs_max(weight, o * K + k0, std::min(s.w_group, K - k0), o);
        s.w_inv[size_t(g * s.w_ld + o)] = gemm_detail::i8_inverse(m);
        s.w_scale[size_t(g * s.w_ld + o)] = gemm_detail::i8_scale(m);
      }
  }
  return s;
}

}  // namespace

void conv2d_winograd(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                     int64_t cin, int64_t cout, float* y, Act act, bool accumulate, WinogradTile tile) {
  if (n <= 0 || h <= 0 || w <= 0 || cout <= 0) return;
  const int ti = tile == WinogradTile::F4x4 ? 1 : 0;
  const int64_t m = ti ? 4 : 2, alpha = m + 2, a2 = alpha * alpha;
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  const wino_detail::WinogradKernels& kern = wino_detail::winograd_kernels(kernel_path());
  const int L = kern.lanes, MR = path.mr;
  if (L != path.nr || MR != kern.rows || MR > wino_detail::kMaxRows)
    throw Error("conv2d (winograd): transform lanes do not match the GEMM panels");
  const int64_t tiles_x = ceil_div(w, m), tpf = ceil_div(h, m) * tiles_x, ntiles = n * tpf;
  const int64_t K = std::max<int64_t>(cin, 1);
  // Precision::Bf16 rounds the convolution's inputs, the input values and the weights, to bfloat16, as the direct
  // convolution does; Int8 quantises them to int8 (winograd.h says with which scales). The transforms and the
  // products of the transformed tiles stay float32.
  const wino_detail::OperandRounding rounding = precision() == Precision::Bf16   ? wino_detail::OperandRounding::Bf16
                                                : precision() == Precision::Int8 ? wino_detail::OperandRounding::Int8
                                                                                 : wino_detail::OperandRounding::None;
  const wino_detail::InputPanelFn input_panel = kern.input[int(rounding)][ti];
  const wino_detail::FilterFn filter_rows = kern.filter[ti];
  const bool int8 = rounding == wino_detail::OperandRounding::Int8 && cin > 0;
  const Int8Scales q8 = int8 ? int8_scales(x, n, h * w, cin, weight, cout, MR) : Int8Scales{};
  const wino_detail::InputQuant input_quant = q8.input();

  const double flops = 18.0 * double(cout) * double(cin) * double(n * h * w);  // direct-equivalent
  const int threads = omp_in_parallel() || flops < gemm_detail::kSerialFlops ? 1 : num_threads();
  const wino_detail::WinogradBlocking blk = wino_detail::winograd_blocking(cin, cout, ntiles, a2, MR, L, threads);
  const bool own_rows = blk.own_rows;
  const int64_t co = blk.co, ncb = blk.ncb, tb = blk.tb, ntb = blk.ntb;
  // Floats per tile position, one cache line more than the matrices need: the transforms read and write all 36 (or
  // 16) positions of a tile together, which at a power-of-two distance would share one L1 set.
  const int64_t u_xi = co * K + 16, v_xi = tb * K + 16, m_xi = co * tb + 16;
  const int64_t u_floats = (a2 * u_xi + 15) / 16 * 16, v_floats = (a2 * v_xi + 15) / 16 * 16;
  float* const U = thread_scratch(size_t(u_floats + v_floats + a2 * m_xi));
  float* const V = U + u_floats;
  float* const Mb = V + v_floats;

  const int64_t npc = ceil_div(K, path.kc), kc_blk = ceil_div(K, npc);
  // The products go by chunks of U's rows, each a whole number of panels and at most an A block: balanced chunks of
  // each thread's share of the block's rows (own_rows) or of all of them. Every chunk re-reads the tile position's
  // V slice, so a share is never cut finer than the A block needs (640 -> 640 on 16x16: 84 rows a thread in two
  // chunks, not seven of one panel, which read V 3.5x as often: 1.5x the time, AMD EPYC Zen 5 class).
  const int64_t share = own_rows ? co / threads : co;
  const int64_t share_chunks = ceil_div(share, std::max<int64_t>(MR, path.a_block_rows(kc_blk) / MR * MR));
  const int64_t chunk_rows = ceil_div(ceil_div(share, share_chunks), MR) * MR;
  const int64_t nchunks = (own_rows ? threads : 1) * share_chunks;
  const int64_t cchunks = ceil_div(K, L);

  // One item: the MR output channels of one A panel times up to L input channels. The path's A packer converts and
  // transposes their weights, g[(c*9 + t)*MR + i] = w(o + i, c0 + c, t) (rows past cout zero); each input channel
  // is then transformed with lanes over the MR output channels into U's packed panel (filter_rows). (Transforming with
  // lanes over input channels instead needs a transpose of all 36 or 16 transformed positions, not of the 9 taps.)
  const auto filter_phase = [&](int64_t cb) {
    const int64_t o0 = cb * co;
    // Zeroed once: the filter transform's spare lanes read up to kFilterOverread floats past the last channel.
    alignas(64) float g[9 * wino_detail::kMaxLanes * wino_detail::kMaxRows + wino_detail::kFilterOverread] = {};
#pragma omp for collapse(2) schedule(static)
    for (int64_t op = 0; op < co / MR; ++op)
      for (int64_t cc = 0; cc < cchunks; ++cc) {
        const int64_t c0 = cc * L, o = o0 + op * MR;
        const int len = int(std::clamp<int64_t>(cin - c0, 1, L));  // cin == 0: one zero column (K = 1)
        const int rows = int(std::clamp<int64_t>(cout - o, 0, MR));
        float* const dst = U + op * MR * K + c0 * MR;
        if (rows == 0 || cin == 0) {
          for (int64_t xi = 0; xi < a2; ++xi) std::fill_n(dst + xi * u_xi, len * MR, 0.0f);
          continue;
        }
        path.pack_a(weight.element((o * cin + c0) * 9), weight.dtype, cin * 9, false,
                    weight.dtype == DType::I8 ? weight.scale + o : nullptr, rows, len * 9, g);
        if (int8) kern.round_taps_i8(g, c0 * 9, len * 9, q8.taps(o));
        if (rounding == wino_detail::OperandRounding::Bf16) kern.round_taps_bf16(g, len * 9 * MR);
        filter_rows(g, len, dst, u_xi);
      }
  };

  const auto tiles_in = [&](int64_t tbi) { return std::min(tb, ntiles - tbi * tb); };
  const auto input_phase = [&](int64_t tbi) {
    const int64_t nt = tiles_in(tbi), panels = ceil_div(nt, L);
    const int64_t cstep = std::max<int64_t>(1, std::min<int64_t>(32, ceil_div(K, 4)));
    const int64_t csteps = ceil_div(K, cstep);
#pragma omp for collapse(2) schedule(static)
    for (int64_t p = 0; p < panels; ++p)
      for (int64_t cs = 0; cs < csteps; ++cs) {
        const int64_t g0 = tbi * tb + p * L;
        const PanelGeom pg = panel_geom(g0, int(std::min<int64_t>(L, nt - p * L)), tiles_x, tpf, h, w);
        const int64_t c0 = cs * cstep, c1 = std::min(K, c0 + cstep);
        if (cin == 0) {
          for (int64_t xi = 0; xi < a2; ++xi) std::fill_n(V + xi * v_xi + p * K * L, L, 0.0f);
          continue;
        }
        input_panel(x, cin, pg, c0, c1, V + p * K * L, v_xi, &input_quant);
      }
  };

  // The products of one tile position xi for one chunk of U's rows, up to the last panel of block cb that holds
  // output channels.
  const auto gemm_chunk = [&](int64_t cb, int64_t panels, int64_t xi, int64_t ch) {
    const int64_t s0 = ch / share_chunks * share, r0 = s0 + ch % share_chunks * chunk_rows;
    const int64_t r1 = std::min({s0 + share, r0 + chunk_rows, ceil_div(cout - cb * co, MR) * MR});
    gemm_detail::TileEpilogue te;
    for (int64_t pc = 0; pc < npc; ++pc) {
      const int64_t k0 = pc * kc_blk, kc = std::min(kc_blk, K - k0);
      te.load_c = pc > 0;
      for (int64_t p = 0; p < panels; ++p) {
        const float* b = V + xi * v_xi + p * K * L + k0 * L;
        for (int64_t r = r0; r < r1; r += MR)
          path.micro(kc, U + xi * u_xi + r * K + k0 * MR, 1, MR, b, Mb + xi * m_xi + r * tb + p * L, tb, MR, L, te);
      }
    }
  };
  const auto gemm_phase = [&](int64_t cb, int64_t tbi) {
    const int64_t panels = ceil_div(tiles_in(tbi), L);
    if (own_rows) {  // thread t takes the chunks of its own rows, as in the filter and output phases
#pragma omp for collapse(2) schedule(static)
      for (int64_t ch = 0; ch < nchunks; ++ch)
        for (int64_t xi = 0; xi < a2; ++xi) gemm_chunk(cb, panels, xi, ch);
    } else {
#pragma omp for collapse(2) schedule(dynamic, 1)
      for (int64_t xi = 0; xi < a2; ++xi)
        for (int64_t ch = 0; ch < nchunks; ++ch) gemm_chunk(cb, panels, xi, ch);
    }
  };

  const auto output_phase = [&](int64_t cb, int64_t tbi) {
    const int64_t nt = tiles_in(tbi), panels = ceil_div(nt, L), o0 = cb * co;
    const int64_t rows = std::min(co, cout - o0);
#pragma omp for collapse(2) schedule(static)
    for (int64_t ol = 0; ol < rows; ++ol)
      for (int64_t p = 0; p < panels; ++p) {
        const PanelGeom pg = panel_geom(tbi * tb + p * L, int(std::min<int64_t>(L, nt - p * L)), tiles_x, tpf, h, w);
        const int64_t o = o0 + ol;
        const wino_detail::OutputEpilogue ep{y, cout, o, bias ? bias[o] : 0.0f, act, accumulate};
        kern.output[ti](Mb + ol * tb + p * L, m_xi, pg, ep);
      }
  };

#pragma omp parallel num_threads(threads) if (threads > 1)
  if (blk.tiles_outside) {
    for (int64_t tbi = 0; tbi < ntb; ++tbi) {
      input_phase(tbi);
      for (int64_t cb = 0; cb < ncb; ++cb) {
        filter_phase(cb);
        gemm_phase(cb, tbi);
        output_phase(cb, tbi);
      }
    }
  } else {
    for (int64_t cb = 0; cb < ncb; ++cb) {
      filter_phase(cb);
      for (int64_t tbi = 0; tbi < ntb; ++tbi) {
        if (ntb > 1 || cb == 0) input_phase(tbi);
        gemm_phase(cb, tbi);
        output_phase(cb, tbi);
      }
    }
  }
}

}  // namespace egopd
