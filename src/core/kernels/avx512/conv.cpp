// AVX-512 convolution kernels: implicit-im2col packing (each 32-column row of a B panel is two masked loads of the
// shifted frame: the validity bits of the tap are the load masks, padding costs nothing and nothing outside the
// frame is read), and the direct 3x3 convolution that multiplies from a small window of the input per output tile
// instead of an im2col panel.
#include <omp.h>

#include <algorithm>
#include <cstdint>

#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"
#include "core/memory.h"
#include "core/threading.h"

#include "core/kernels/avx512/isa.h"

#include "core/kernels/avx512/tile.h"

namespace egopd::conv_detail {

void pack_im2col_shift_avx512(const float* xf, const ShiftGeom& s, int64_t k0, int64_t kc, int64_t n0, int nr,
                              float* dst) {
  constexpr int NR = gemm_detail::kNrAvx512;
  ShiftRows rows(xf, s, k0, n0, nr);
  for (int64_t k = 0; k < kc; ++k) {
    uint32_t m;
    const float* src = rows.next(&m);
    // The next panel reads the following 64 bytes of the same rows: fetch them into L2 now (each row is its own
    // stream, far more than the hardware prefetchers track).
    _mm_prefetch(reinterpret_cast<const char*>(src + NR), _MM_HINT_T1);
    _mm_prefetch(reinterpret_cast<const char*>(src + NR + 16), _MM_HINT_T1);
    _mm512_store_ps(dst + k * NR, _mm512_maskz_loadu_ps(__mmask16(m), src));
    _mm512_store_ps(dst + k * NR + 16, _mm512_maskz_loadu_ps(__mmask16(m >> 16), src + 16));
  }
}

}  // namespace egopd::conv_detail

// ---- Direct 3x3 convolution without an im2col panel --------------------------------------------------------
// Stride 1, padding 1, float32, frames whose width is a multiple of 16. Output tile: 12 output channels x 32
// pixels at flat index n0 of a frame, as two halves of 16 pixels, each inside one row (the width being a multiple
// of 16). For one K pass, the tile's input window (per channel, per half, the three rows around it, columns -1 to
// 16 of the half, zeros outside the frame) is copied into a small contiguous buffer, and the micro-kernel reads
// tap (ky, kx) of half h as 16 floats at column kx of that row. The implicit GEMM's im2col panel holds every
// input value nine times (one row per tap) and took about a fifth of its time to pack on the VAE's 128-channel
// 256x256 layers; the window holds it about once. It is also contiguous: read in place, the rows of consecutive
// channels lie a plane apart, a power of two on the models' frames, and all fall into the same L1 cache set.

namespace egopd::conv_detail {

namespace {

using gemm_detail::MR;
using gemm_detail::NR;

constexpr int64_t kPassChannels = 32;        // input channels of a K pass: a 24 KiB window, in L1
constexpr int64_t kWindowRow = 32;           // floats of one row of the window (18 used), two cache lines
constexpr int64_t kBlockCBytes = 256 << 10;  // output tiles of a block: their sums stay in L2 across the K passes
constexpr int64_t kMaxPackedA = 16 << 20;    // bytes of packed filters; larger layers take the implicit GEMM

// win[((c*3 + ky)*2 + half)*kWindowRow + j] = frame value at channel c, row y_half + ky - 1, column
// x_half - 1 + j (j < 18), zero outside the frame, for the tile at flat index n0 (nr valid pixels).
void pack_window(const float* xc, int64_t plane, int64_t h, int64_t w, int64_t n0, int nr, int64_t nc, float* win) {
  __mmask16 lo[3][2], hi[3][2];
  int64_t off[3][2];
  for (int half = 0; half < 2; ++half) {
    const int64_t p = n0 + 16 * half, y = p / w, x = p % w;
    for (int ky = 0; ky < 3; ++ky) {
      const bool row = 16 * half < nr && y + ky - 1 >= 0 && y + ky - 1 < h;
      lo[ky][half] = row ? __mmask16(x == 0 ? 0xfffe : 0xffff) : __mmask16(0);       // columns x-1 .. x+14
      hi[ky][half] = row ? __mmask16(x + 16 == w ? 0x1 : 0x3) : __mmask16(0);         // columns x+15, x+16
      off[ky][half] = row ? (y + ky - 1) * w + x - 1 : 0;  // masked-off lanes are never read
    }
  }
  for (int64_t c = 0; c < nc; ++c, xc += plane)
    for (int ky = 0; ky < 3; ++ky)
      for (int half = 0; half < 2; ++half) {
        const float* src = xc + off[ky][half];
        float* dst = win + ((c * 3 + ky) * 2 + half) * kWindowRow;
        _mm_prefetch(reinterpret_cast<const char*>(src + 32), _MM_HINT_T0);  // the next tile's window
        _mm512_store_ps(dst, _mm512_maskz_loadu_ps(lo[ky][half], src));
        _mm512_store_ps(dst + 16, _mm512_maskz_loadu_ps(hi[ky][half], src + 16));
      }
}

// sum (R x NR of an MR x NR row-major tile) = (add ? sum : 0) + rows 0..R-1 of the A panel
// (a[(c*9 + t)*MR + i], nc input channels) times the window's taps. R < MR for the last panel of a cout that is
// not a multiple of 12 (128 = 10*12 + 8 in the VAE: a full tile there wasted 3% of the work).
template <int R>
void window_tile(const float* win, int64_t nc, const float* a, float* sum, bool add) {
  __m512 c0[R], c1[R];
#pragma GCC unroll 12
  for (int i = 0; i < R; ++i) {
    c0[i] = add ? _mm512_load_ps(sum + i * NR) : _mm512_setzero_ps();
    c1[i] = add ? _mm512_load_ps(sum + i * NR + 16) : _mm512_setzero_ps();
  }
  // Tap t = ky*3 + kx of half 0 at row ky of the window, column kx (half 1: one window row further).
  static constexpr int64_t kTap[9] = {0, 1, 2, 2 * kWindowRow, 2 * kWindowRow + 1, 2 * kWindowRow + 2,
                                      4 * kWindowRow, 4 * kWindowRow + 1, 4 * kWindowRow + 2};
  for (int64_t c = 0; c < nc; ++c, win += 6 * kWindowRow) {
    // One tap per iteration, as in the GEMM's k loop: unrolled, GCC hoists the broadcasts and spills accumulators.
#pragma GCC unroll 1
    for (int t = 0; t < 9; ++t) {
      const float* src = win + kTap[t];
      const __m512 b0 = _mm512_loadu_ps(src), b1 = _mm512_loadu_ps(src + kWindowRow);
#pragma GCC unroll 12
      for (int i = 0; i < R; ++i) {
        const __m512 av = _mm512_set1_ps(a[i]);
        c0[i] = _mm512_fmadd_ps(av, b0, c0[i]);
        c1[i] = _mm512_fmadd_ps(av, b1, c1[i]);
      }
      a += MR;
    }
  }
#pragma GCC unroll 12
  for (int i = 0; i < R; ++i) {
    _mm512_store_ps(sum + i * NR, c0[i]);
    _mm512_store_ps(sum + i * NR + 16, c1[i]);
  }
}

void window_tile_rows(int mr, const float* win, int64_t nc, const float* a, float* sum, bool add) {
  if (mr > 8) window_tile<MR>(win, nc, a, sum, add);
  else if (mr > 4) window_tile<8>(win, nc, a, sum, add);
  else window_tile<4>(win, nc, a, sum, add);
}

}  // namespace

bool conv3x3_window_avx512(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
                           int64_t cin, int64_t cout, float* y, Act act, bool accumulate) {
  using namespace gemm_detail;
  const int64_t K = cin * 9;
  if (w % 16 != 0 || n <= 0 || h <= 0 || cin <= 0 || cout <= 0) return false;
  const int64_t npass = (cin + kPassChannels - 1) / kPassChannels, cb = (cin + npass - 1) / npass;
  const int64_t mpanels = (cout + MR - 1) / MR, kc_max = cb * 9;
  const int64_t panel_floats = MR * kc_max, a_floats = npass * mpanels * panel_floats;
  if (a_floats * 4 > kMaxPackedA) return false;
  const GemmPath& path = gemm_path(KernelPath::Avx512);
  const int64_t plane = h * w, tpf = (plane + NR - 1) / NR, tiles = n * tpf;
  const int64_t block_tiles = std::max<int64_t>(1, kBlockCBytes / (mpanels * MR * NR * 4));
  int threads = omp_in_parallel() ? 1 : num_threads();
  if (2.0 * double(n * plane) * double(cout * K) < kSerialFlops) threads = 1;
  threads = int(std::min<int64_t>(threads, std::max<int64_t>(tiles / block_tiles, 1)));

  Operand wa = weight;  // [cout, cin*9] row-major
  wa.trans = false;
  wa.ld = K;
  const OperandA a_src(wa);
  // The calling thread's scratch: the packed filters, shared by the team (read only), then a window and a block
  // of sums per thread.
  thread_local AlignedScratch tl_scratch;
  // Several K passes: the block's partial sums go to a contiguous buffer of the thread's, not to y, whose rows lie a
  // plane apart (a power of two on the models' frames: all fall into one L2 set, and the block left L2 between
  // passes: 0.81x oneDNN's blocked convolution on the VAE's 128-channel 256x256 layer).
  const int64_t win_floats = cb * 6 * kWindowRow, win_at = (a_floats + 15) / 16 * 16;  // windows 64-byte aligned
  const int64_t tile_floats = MR * NR, sums_floats = block_tiles * mpanels * tile_floats;
  const int64_t thread_floats = win_floats + sums_floats;
  float* const apack = tl_scratch.get(size_t(win_at + threads * thread_floats));
  const auto panel = [&](int64_t pass, int64_t q) { return apack + (pass * mpanels + q) * panel_floats; };

#pragma omp parallel num_threads(threads) if (threads > 1)
  {
#pragma omp for schedule(static)
    for (int64_t u = 0; u < npass * mpanels; ++u) {
      const int64_t pass = u / mpanels, q = u % mpanels, c0 = pass * cb, nc = std::min(cb, cin - c0);
      a_src.pack(path, q * MR, int(std::min<int64_t>(MR, cout - q * MR)), c0 * 9, nc * 9, panel(pass, q));
    }
    // Contiguous tiles per thread (neighbouring tiles share input rows), in blocks whose sums stay in L2.
    const int nth = omp_get_num_threads(), tid = omp_get_thread_num();
    const int64_t t_lo = tiles * tid / nth, t_hi = tiles * (tid + 1) / nth;
    float* const win = apack + win_at + tid * thread_floats;
    float* const sums = win + win_floats;
    // Tile t: frame f, pixels n0 .. n0 + nr - 1; its sums for row panel q in the thread's block starting at b0.
    const auto tile_at = [&](int64_t t) { return pixel_panel(t, tpf, plane, NR); };
    const auto sums_of = [&](int64_t b0, int64_t t, int64_t q) { return sums + ((t - b0) * mpanels + q) * tile_floats; };
    // Its outputs: channel m0 of frame f from pixel n0 (rows a plane apart).
    const auto out_at = [&](int64_t f, int64_t m0, int64_t n0) { return y + (f * cout + m0) * plane + n0; };
    TileEpilogue te;  // the last pass's: the earlier ones only add into the sums
    te.act = act;
    te.load_c = accumulate && act == Act::None;
    te.add_after = accumulate && act != Act::None;
    for (int64_t b0 = t_lo; b0 < t_hi; b0 += block_tiles) {
      const int64_t b1 = std::min(t_hi, b0 + block_tiles);
      for (int64_t pass = 0; pass < npass; ++pass) {
        const int64_t c0 = pass * cb, nc = std::min(cb, cin - c0);
        for (int64_t t = b0; t < b1; ++t) {
          const auto [f, n0, nr] = tile_at(t);
          pack_window(x + (f * cin + c0) * plane, plane, h, w, n0, nr, nc, win);
          for (int64_t q = 0; q < mpanels; ++q) {
            const int mr = int(std::min<int64_t>(MR, cout - q * MR));
            window_tile_rows(mr, win, nc, panel(pass, q), sums_of(b0, t, q), pass > 0);
            // The last pass: fetch the tile's output rows into L2 while the products run, so that the block's
            // stores below do not each wait for their line.
            if (pass == npass - 1) {
              const float* c = out_at(f, q * MR, n0);
              for (int i = 0; i < mr; ++i) {
                _mm_prefetch(reinterpret_cast<const char*>(c + i * plane), _MM_HINT_T1);
                _mm_prefetch(reinterpret_cast<const char*>(c + i * plane + 16), _MM_HINT_T1);
              }
            }
          }
        }
      }
      // The block's outputs, 12 channels at a time: each channel's pixels written in order (12 write streams; tile
      // by tile, all channels at once, were 132 streams a plane apart and cost about a tenth of the time).
      for (int64_t q = 0; q < mpanels; ++q) {
        const int64_t m0 = q * MR;
        const int mr = int(std::min<int64_t>(MR, cout - m0));
        te.bias_row = bias ? bias + m0 : nullptr;
        for (int64_t t = b0; t < b1; ++t) {
          const auto [f, n0, nr] = tile_at(t);
          float* c = out_at(f, m0, n0);
          prefetch_c(c, plane, mr);
          store_tile(sums_of(b0, t, q), c, plane, mr, nr, te);
        }
      }
    }
  }
  return true;
}

}  // namespace egopd::conv_detail
