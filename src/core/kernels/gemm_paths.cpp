// The GEMM engine's kernel paths and their blocking, derived once from the CPU's cache sizes.
#include <algorithm>
#include <cstdlib>

#include "core/kernels/conv_internal.h"
#include "core/kernels/gemm_internal.h"

namespace egopd::gemm_detail {

namespace {

int64_t env_int(const char* name, int64_t fallback) {
  const char* e = std::getenv(name);
  if (!e || !*e) return fallback;
  char* end = nullptr;
  const long long v = std::strtoll(e, &end, 10);
  return end && *end == '\0' && v > 0 ? int64_t(v) : fallback;
}

// Blocking from the cache sizes (EGOPD_GEMM_KC / EGOPD_GEMM_MC override KC and MC for tuning experiments).
enum class BlockRule {
  // Portable and NEON: a KC x NR B micro-panel fills 3/4 of L1 (it is reused by every A micro-panel of a block,
  // which stream from L2), at most 512; an MC x KC A block fills 9/16 of L2 (384 / 192 on a 32 KiB L1 / 512 KiB
  // L2 core).
  L1Panel,
  // AVX-512: it computes twice as fast per cycle, so re-reading C between K passes costs more than keeping the B
  // micro-panel in L1 saves: its KC x 32 B micro-panel takes 1/6 of L2 (streamed from L2 by the hardware
  // prefetcher) and its A block 1/4 of L2. On a 1 MiB L2 core: KC = 1344, MC = 48, so the U-Net's 1280-deep
  // products take one K pass. bench gemm, AMD EPYC Zen 5 class, 2 threads, against KC = 672 / MC = 96 (the best
  // of an earlier one-thread scan, before the C tile was prefetched and read ahead of its stores): 1024x1280x1280
  // 84 -> 90% of peak, 16384x320x1280 87 -> 92%, 4096x640x2560 85 -> 89%, 1024x10240x1280 81 -> 88%, 640-deep
  // shapes even.
  L2PanelQuarterA,
  // AVX2: the same 1/6 of L2 for its KC x 16 B micro-panel, and an A block of all of L2 (read in place, rows
  // lda apart; the part that L2 does not hold comes from L3 in the prefetcher's stream). On a 512 KiB L2 core:
  // KC = 1344, MC = 96 against the L1 rule's 384 / 192, which passes no deeper than 384 keep (GemmPath::kc_shallow).
  // AMD EPYC Zen 3, 2 threads, alternating with the L1 rule (BENCHMARKS.md, twenty-fifth session): 1280-deep
  // products 0.84-0.89x the time, 640-deep 0.82-0.96x, 5120-deep 0.95x; U-Net fp32 0.95x, VAE decode 0.94-0.95x.
  L2PanelWholeA,
};

GemmPath with_blocking(GemmPath p, BlockRule rule) {
  const CpuInfo& ci = cpu_info();
  const int64_t l1 = ci.l1d_bytes(), l2 = ci.l2_bytes();
  const int64_t panel_bytes = p.nr * 4;  // of one k step of a B micro-panel
  const auto rows_in = [&](int64_t a_bytes, int64_t kc) {  // of an A block of a_bytes at depth kc
    return std::max<int64_t>(a_bytes / (kc * 4) / p.mr * p.mr, p.mr);
  };
  const int64_t kc_l1 = std::clamp<int64_t>(l1 * 3 / 4 / panel_bytes / 16 * 16, 128, 512);
  int64_t kc = rule == BlockRule::L1Panel ? kc_l1 : std::clamp<int64_t>(l2 / 6 / panel_bytes / 32 * 32, 128, 2048);
  kc = std::clamp<int64_t>(env_int("EGOPD_GEMM_KC", kc), 16, 4096);
  const int64_t a_bytes = rule == BlockRule::L1Panel ? l2 * 9 / 16 : rule == BlockRule::L2PanelQuarterA ? l2 / 4 : l2;
  const int64_t mc = rows_in(a_bytes, kc);
  const auto tuned = [&](int64_t rows) {
    return std::max<int64_t>(env_int("EGOPD_GEMM_MC", rows) / p.mr * p.mr, p.mr);
  };
  p.mc = p.mc_i8 = tuned(mc);
  if (rule == BlockRule::L2PanelWholeA) {
    // Passes no deeper than the L1 rule's KC keep its B micro-panel in L1 and its A blocks, and int8 keeps them
    // too (quads of bytes, K passes set by the quantisation groups; 96 rows were 4-10% slower in the U-Net).
    p.kc_shallow = kc_l1;
    p.mc_shallow = p.mc_i8 = tuned(rows_in(l2 * 9 / 16, kc_l1));
  }
  p.kc = kc;
  p.nc = 2048;
  return p;
}

// Int8 by the exact scalar micro-kernel (signed quads), for paths without an int8 dot product.
template <int MR, int NR>
GemmPath with_emulated_int8(GemmPath p) {
  p.quantize_a_i8 = p.quantize_b_i8 = [](const float* src, float* dst, int width, int64_t kc, int64_t group) {
    quantize_i8_quads(src, dst, width, kc, group, false);
  };
  p.micro_i8 = microkernel_i8_portable<MR, NR>;
  p.i8_kernel = "emulated";
  return p;
}

}  // namespace

const GemmPath& gemm_path(KernelPath which) {
  using namespace conv_detail;
  static const GemmPath portable = [] {
    GemmPath p = with_emulated_int8<kMrPortable, kNrPortable>(
        with_blocking({kMrPortable, kNrPortable, microkernel_portable, true, pack_a_portable<kMrPortable>,
                       pack_b_portable<kNrPortable>, pack_im2col_shift_portable, nullptr},
                      BlockRule::L1Panel));
    p.pack_b_temporal_wino = pack_b_temporal_wino_portable<kNrPortable>;
    p.temporal_wino_output = temporal_wino_output_portable<kNrPortable>;
    return p;
  }();
#if defined(__x86_64__)
  static const GemmPath avx2 = [] {
    GemmPath p = with_blocking({kMrAvx2, kNrAvx2, microkernel_avx2, true, pack_a_avx2, pack_b_avx2,
                                pack_im2col_shift_avx2, pack_a_temporal6_avx2},
                               BlockRule::L2PanelWholeA);
    p.pack_b_temporal_wino = pack_b_temporal_wino_avx2;
    p.temporal_wino_output = temporal_wino_output_avx2;
    p.quantize_a_i8 = quantize_i8_a_avx2;
    p.quantize_b_i8 = quantize_i8_b_avx2;
    p.i8_b_levels = kI8LevelsAvx2B;
    p.pack_a_i8 = pack_a_i8_rows_avx2<kMrAvx2>;
    p.pack_b_i8 = pack_b_i8_rows_avx2;
    p.micro_i8 = microkernel_avx2_i8;
    p.i8_kernel = "vpmaddubsw (AVX2, B in 63 levels)";
    // Float32 Winograd beats vpmaddubsw's direct convolution on the VAE's frames and the U-Net's 16x16 and 32x32
    // (BENCHMARKS.md, twenty-second session), and on its 16 x 8x8 too since the twenty-fifth's blocking (AMD EPYC
    // Zen 3, bench conv2d alternating: 1280 -> 1280 0.75x the time, 640 / 1920 / 2560 -> 1280 0.75-0.96x); its 4x4
    // stay direct as in float32. vpdpbusd's beats Winograd on every VAE layer.
    p.i8_winograd_min_frame = 8;
    // F(2x2) against the direct convolution, 1280 -> 1280 channels, float32 (AMD EPYC Zen 3, 2 threads, bench conv2d,
    // three alternating rounds): 16 frames of 4x4 (256 pixels) 0.63x the time (one thread 0.6x, bf16 0.82x, 2560 ->
    // 1280 0.74-0.89x), 16 of 6x6 0.63x, 8 of 4x4 0.8-1.1x, 4 of 4x4 even, 1 of 4x4 2.5x.
    p.winograd_f2_min_pixels = p.winograd_f2_min_pixels_bf16 = 256;
    // Temporal convolutions: F(2,3) on quantised transforms 0.72-0.83x the time of the int8 direct convolution on the
    // U-Net's and the VAE decoder's layers (AMD EPYC Zen 3, kernels_bench alternating, 128-1280 channels).
    p.i8_temporal_winograd = true;
    return p;
  }();
  static const GemmPath avx512 = [] {
    GemmPath p = with_blocking({kMrAvx512, kNrAvx512, microkernel_avx512, true, pack_a_avx512, pack_b_avx512,
                                pack_im2col_shift_avx512, pack_a_temporal12_avx2},
                               BlockRule::L2PanelQuarterA);
    p.conv3x3_window = conv3x3_window_avx512;
    p.pack_b_temporal_wino = pack_b_temporal_wino_avx512;
    p.temporal_wino_output = temporal_wino_output_avx512;
    // F(2x2) against the direct convolution on 16 frames of 4x4 (256 pixels), float32 (AMD EPYC Zen 4, 2 threads,
    // bench conv2d, five alternating rounds, since the filter transform writes whole runs): 1280 -> 1280 0.53-0.92x
    // the time, 2560 -> 1280 0.91-0.96x; under bf16 (vdpbf16ps) 1.04-1.8x, so there 4x4 frames stay direct.
    p.winograd_f2_min_pixels = p.winograd_f2_min_pixels_bf16 = 256;
    if (cpu_info().avx512_bf16) {
      p.winograd_f2_min_pixels_bf16 = 1024;
      // F(4x4) against the direct convolution under bf16, 16 frames (AMD EPYC Zen 5 class, 2 threads, bench conv2d,
      // three alternating rounds): 1280 -> 1280 on 8x8 1.2-1.4x the time, 10x10 1.5x, 12x12 0.91-0.96x, 14x14 1.1x,
      // 16x16 0.96-1.07x; 2560 / 1920 / 640 -> 1280 on 8x8 1.1-1.4x; 320 -> 320 on 32x32 0.74x.
      p.winograd_f4_min_frame_bf16 = 16;
      // Temporal F(2,3) against the direct convolution under bf16, 16 frames (same host, kernels_bench, two
      // alternating rounds): 1280 channels of 64 pixels 1.07-1.09x the time, 640 of 256 0.70x, 320 of 1024 0.72x.
      p.temporal_winograd_min_pixels_bf16 = 128;
      p.to_bf16_pairs = to_bf16_pairs_avx512;
      p.micro_bf16 = microkernel_avx512_bf16;
      p.pack_a_bf16 = pack_a_bf16_avx512;
      p.pack_b_bf16 = pack_b_bf16_avx512;
    }
    p = with_emulated_int8<kMrAvx512, kNrAvx512>(p);
    if (cpu_info().avx512_vnni) {
      p.quantize_a_i8 = quantize_i8_a_avx512_vnni;
      p.quantize_b_i8 = quantize_i8_b_avx512_vnni;
      p.micro_i8 = microkernel_avx512_vnni;
      p.pack_a_i8 = pack_a_i8_rows_avx2<kMrAvx512>;  // the same unsigned quads of 127 levels
      p.i8_kernel = "vpdpbusd (AVX512-VNNI)";
    }
    return p;
  }();
  if (which == KernelPath::Avx512) return avx512;
  if (which == KernelPath::Avx2) return avx2;
#elif defined(__aarch64__)
  // A is always packed (an 8-row column is two loads; in place it would be eight).
  static const GemmPath neon = [] {
    GemmPath p = with_emulated_int8<kMrNeon, kNrNeon>(
        with_blocking({kMrNeon, kNrNeon, microkernel_neon, false, pack_a_neon, pack_b_neon, pack_im2col_shift_neon,
                       nullptr},
                      BlockRule::L1Panel));
    // NEON is the AArch64 baseline: the compiler vectorises the portable packer with it.
    p.pack_b_temporal_wino = pack_b_temporal_wino_portable<kNrNeon>;
    p.temporal_wino_output = temporal_wino_output_portable<kNrNeon>;
    if (cpu_info().neon_dotprod) {  // the emulation's quads and numbers, multiplied by sdot
      p.micro_i8 = microkernel_neon_sdot;
      p.i8_kernel = "sdot (ARMv8.2 dot product)";
    }
    return p;
  }();
  if (which == KernelPath::Neon) return neon;
#endif
  return portable;
}

const GemmPath& gemm_path() { return gemm_path(kernel_path()); }

}  // namespace egopd::gemm_detail
