// Winograd F(m x m, 3x3) driver. For a block of output channels and a block of tiles: filter transform (U, packed
// as the GEMM's A panels), input transform (V, packed as its B panels), alpha^2 GEMMs M_xi = U_xi · V_xi on the
// path's micro-kernel (the transforms write the packed layouts directly, so no packing pass), output transform with
// the conv2d epilogue. One parallel region per call; each phase is a work-shared loop (barrier between phases).
//
// Memory: the transformed filters are recomputed on every call, never kept (a transformed copy of every 3x3 filter
// would be 4x (F(4x4): 36/9) the fp32 weights, 8x the stored F16 ones: several GB for the U-Net). U is blocked over
// output channels to kFilterBudget bytes, V and M over tiles to kTileBudget bytes; the scratch is the calling
// thread's, grown on demand and kept like the GEMM's packing scratch.
#include "core/kernels/winograd.h"

#include <omp.h>

#include <algorithm>
#include <string>

#include "core/error.h"
#include "core/kernels/elementwise.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"
#include "core/kernels/winograd_transforms.h"
#include "core/memory.h"
#include "core/threading.h"

namespace egopd {

namespace wino_detail {

void apply_act_inplace(Act act, float* v, int64_t n) {
  switch (act) {
    case Act::None: return;
    case Act::SiLU: return silu_inplace(v, n);
    case Act::GELU: return gelu_inplace(v, n);
    case Act::QuickGELU: return quick_gelu_inplace(v, n);
  }
}

const WinogradKernels& winograd_kernels_portable() {
  static const WinogradKernels k = make_winograd_kernels<gemm_detail::kNrPortable>();
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

constexpr int64_t kFilterBudget = int64_t(16) << 20;  // bytes of U (one block of output channels)
constexpr int64_t kTileBudget = int64_t(4) << 20;     // bytes of V + M (one block of tiles)
// Fewest tiles per block: U is re-read from memory for every block, >= 64 flops per byte of it.
constexpr int64_t kMinBlockTiles = 128;
constexpr double kSerialFlops = 4e5;                  // direct-equivalent flops below which one thread runs

int64_t ceil_div(int64_t a, int64_t b) { return (a + b - 1) / b; }

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

// g[t*L + j] = weight(o, c0 + j, tap t) for j < len (dequantised), 0 for len <= j < L.
void load_filters(const Operand& wt, int64_t cin, int64_t o, int64_t c0, int len, int L, float* g) {
  const int64_t base = (o * cin + c0) * 9;
  const auto gather = [&](const auto* src, auto convert) {
    for (int j = 0; j < len; ++j)
      for (int t = 0; t < 9; ++t) g[t * L + j] = convert(src[base + j * 9 + t]);
  };
  switch (wt.dtype) {
    case DType::F32: gather(static_cast<const float*>(wt.data), [](float v) { return v; }); break;
    case DType::F16: gather(static_cast<const uint16_t*>(wt.data), half_to_float); break;
    case DType::BF16: gather(static_cast<const uint16_t*>(wt.data), bf16_to_float); break;
    default: {
      const float scale = wt.scale[o];
      gather(static_cast<const int8_t*>(wt.data), [scale](int8_t q) { return float(q) * scale; });
    }
  }
  for (int t = 0; t < 9; ++t)
    for (int j = len; j < L; ++j) g[t * L + j] = 0.0f;
}

}  // namespace

const char* winograd_tile_name(WinogradTile t) { return t == WinogradTile::F4x4 ? "F(4x4,3x3)" : "F(2x2,3x3)"; }

WinogradTile winograd_tile_for(int64_t h, int64_t w) {
  // A 4x4 tile reads a 6x6 patch: on a frame narrower than 8 most of it is padding.
  return std::min(h, w) >= 8 ? WinogradTile::F4x4 : WinogradTile::F2x2;
}

bool winograd_wins(int64_t cin, int64_t cout, int64_t n, int64_t h, int64_t w) {
  // Few channels: the transforms (O(cin + cout) per tile) outweigh the GEMM saving (O(cin * cout) per tile).
  // Frames under 4 pixels: edge tiles are mostly padding. Few pixels in all: the per-call filter transform (per
  // channel pair about 60 ns for F(4x4) on one Zen 5 core, less for F(2x2): 16 values instead of 36) is not paid
  // back by the GEMM saving per pixel. Measured on 1280 channels, one thread: F(4x4) 8x8 loses 2x at 4 frames (256 pixels) and
  // wins 1.2x at 16 (1024 pixels); F(2x2) 4x4 wins 1.1x at 16 frames (256 pixels) and 1.5x at 32.
  if (cin < 16 || cout < 16 || std::min(h, w) < 4) return false;
  return n * h * w >= (winograd_tile_for(h, w) == WinogradTile::F4x4 ? 1024 : 512);
}

void conv2d_winograd(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                     int64_t cin, int64_t cout, float* y, Act act, bool accumulate, WinogradTile tile) {
  if (n <= 0 || h <= 0 || w <= 0 || cout <= 0) return;
  const int ti = tile == WinogradTile::F4x4 ? 1 : 0;
  const int64_t m = ti ? 4 : 2, alpha = m + 2, a2 = alpha * alpha;
  const gemm_detail::GemmPath& path = gemm_detail::gemm_path();
  const wino_detail::WinogradKernels& kern = wino_detail::winograd_kernels(kernel_path());
  const int L = kern.lanes, MR = path.mr;
  if (L != path.nr || MR > wino_detail::kMaxRows)
    throw Error("conv2d (winograd): transform lanes do not match the GEMM panels");
  const int64_t tiles_x = ceil_div(w, m), tpf = ceil_div(h, m) * tiles_x, ntiles = n * tpf;
  const int64_t K = std::max<int64_t>(cin, 1);

  // Output-channel blocks (rows of U), then tile blocks (columns of V and M), each a whole number of panels.
  int64_t co = std::max<int64_t>(MR, kFilterBudget / (a2 * K * 4) / MR * MR);
  const int64_t ncb = ceil_div(cout, co);
  co = ceil_div(ceil_div(cout, ncb), MR) * MR;
  int64_t tb = std::max(kMinBlockTiles, kTileBudget / (a2 * (K + co) * 4)) / L * L;
  const int64_t ntb = ceil_div(ntiles, tb);
  tb = ceil_div(ceil_div(ntiles, ntb), L) * L;

  const int64_t u_xi = co * K, v_xi = tb * K, m_xi = co * tb;  // floats per tile position
  const int64_t u_floats = (a2 * u_xi + 15) / 16 * 16, v_floats = (a2 * v_xi + 15) / 16 * 16;
  float* const U = thread_scratch(size_t(u_floats + v_floats + a2 * m_xi));
  float* const V = U + u_floats;
  float* const Mb = V + v_floats;

  const int64_t npc = ceil_div(K, path.kc), kc_blk = ceil_div(K, npc);
  const int64_t chunk_rows = std::min<int64_t>(co, std::max<int64_t>(MR, path.mc / MR * MR));
  const int64_t nchunks = ceil_div(co, chunk_rows);
  const int64_t cchunks = ceil_div(K, L);

  // One item: the MR output channels of one A panel times L input channels, so that U is written as whole
  // contiguous runs of the packed panel (writing it channel by channel touches every cache line MR times).
  const auto filter_phase = [&](int64_t cb) {
    const int64_t o0 = cb * co;
    alignas(64) float g[9 * wino_detail::kMaxLanes];
    alignas(64) float u[wino_detail::kMaxRows][36 * wino_detail::kMaxLanes];
#pragma omp for collapse(2) schedule(static)
    for (int64_t op = 0; op < co / MR; ++op)
      for (int64_t cc = 0; cc < cchunks; ++cc) {
        const int64_t c0 = cc * L;
        const int len = int(std::clamp<int64_t>(cin - c0, 1, L));  // cin == 0: one zero column (K = 1)
        for (int i = 0; i < MR; ++i) {
          const int64_t o = o0 + op * MR + i;
          if (o < cout && cin > 0) {
            load_filters(weight, cin, o, c0, len, L, g);
            kern.filter[ti](g, u[i]);
          } else {
            std::fill_n(u[i], a2 * L, 0.0f);
          }
        }
        for (int64_t xi = 0; xi < a2; ++xi) {
          float* d = U + xi * u_xi + op * MR * K + c0 * MR;
          for (int j = 0; j < len; ++j)
            for (int i = 0; i < MR; ++i) d[j * MR + i] = u[i][xi * L + j];
        }
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
        kern.input[ti](x, cin, pg, c0, c1, V + p * K * L, v_xi);
      }
  };

  const auto gemm_phase = [&](int64_t tbi) {
    const int64_t panels = ceil_div(tiles_in(tbi), L);
#pragma omp for collapse(2) schedule(dynamic, 1)
    for (int64_t xi = 0; xi < a2; ++xi)
      for (int64_t ch = 0; ch < nchunks; ++ch) {
        const int64_t r0 = ch * chunk_rows, r1 = std::min(co, r0 + chunk_rows);
        gemm_detail::TileEpilogue te;
        for (int64_t pc = 0; pc < npc; ++pc) {
          const int64_t k0 = pc * kc_blk, kc = std::min(kc_blk, K - k0);
          te.load_c = pc > 0;
          for (int64_t p = 0; p < panels; ++p) {
            const float* b = V + xi * v_xi + p * K * L + k0 * L;
            for (int64_t r = r0; r < r1; r += MR)
              path.micro(kc, U + xi * u_xi + r * K + k0 * MR, 1, MR, b, Mb + xi * m_xi + r * tb + p * L, tb, MR, L,
                         te);
          }
        }
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

  const double flops = 18.0 * double(cout) * double(cin) * double(n * h * w);
  int threads = omp_in_parallel() ? 1 : num_threads();
  if (flops < kSerialFlops) threads = 1;
  // Output-channel blocks outside, tile blocks inside: V is recomputed for each block of output channels unless
  // all tiles fit one block (the filter budget keeps that to 2-3 blocks on the largest layers).
#pragma omp parallel num_threads(threads) if (threads > 1)
  for (int64_t cb = 0; cb < ncb; ++cb) {
    filter_phase(cb);
    for (int64_t tbi = 0; tbi < ntb; ++tbi) {
      if (ntb > 1 || cb == 0) input_phase(tbi);
      gemm_phase(tbi);
      output_phase(cb, tbi);
    }
  }
}

}  // namespace egopd
