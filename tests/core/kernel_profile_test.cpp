// The kernel profile (core/kernels/kernel_profile.h): nothing recorded while off; per kernel shape, one call and
// the direct float32 flop count of each call while on; a convolution's inner GEMMs are part of the convolution.
#include <gtest/gtest.h>

#include <vector>

#include "core/kernels/attention.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/kernels/kernel_profile.h"

namespace egopd {
namespace {

struct ProfilingOn {
  ProfilingOn() {
    clear_kernel_profile();
    set_kernel_profiling(true);
  }
  ~ProfilingOn() {
    set_kernel_profiling(false);
    clear_kernel_profile();
  }
};

void small_gemm() {
  std::vector<float> a(7 * 11, 0.5f), b(11 * 9, 0.25f), c(7 * 9);
  gemm(7, 9, 11, f32_operand(a.data(), 11), f32_operand(b.data(), 9), c.data(), 9);
}

TEST(KernelProfile, RecordsNothingWhileOff) {
  clear_kernel_profile();
  set_kernel_profiling(false);
  small_gemm();
  EXPECT_TRUE(kernel_profile().empty());
}

TEST(KernelProfile, CountsCallsAndFlopPerShape) {
  ProfilingOn on;
  small_gemm();
  small_gemm();
  const auto p = kernel_profile();
  ASSERT_EQ(p.size(), 1u);
  EXPECT_EQ(p[0].kernel, "gemm 7x9x11 A F32 B F32");
  EXPECT_EQ(p[0].calls, 2);
  EXPECT_EQ(p[0].flop, 2 * 2.0 * 7 * 9 * 11);
  EXPECT_GT(p[0].seconds, 0.0);
}

TEST(KernelProfile, ConvolutionsCountOnceWithTheirOwnFlop) {
  ProfilingOn on;
  // 2 images of 3 -> 5 channels, 6 x 7 pixels, 3x3 stride 1 pad 1: every output takes cin * 9 multiply-adds.
  Conv2dGeom g;
  g.cin = 3, g.cout = 5, g.kh = g.kw = 3, g.pad_h = g.pad_w = 1;
  std::vector<float> x(2 * 3 * 6 * 7, 0.5f), w(5 * 3 * 9, 0.25f), y(2 * 5 * 6 * 7);
  conv2d(x.data(), 2, 6, 7, f32_operand(w.data(), 27), nullptr, g, y.data());
  // Temporal 3x1x1 over a 4-frame clip: 3 * 4 - 2 = 10 frame taps per pixel (edge frames miss one).
  std::vector<float> xt(4 * 3 * 10, 0.5f), wt(5 * 3 * 3, 0.25f), yt(4 * 5 * 10);
  conv_temporal3(xt.data(), 1, 4, 3, 10, f32_operand(wt.data(), 9), nullptr, 5, yt.data());
  // Causal attention over 6 tokens: 1 + 2 + ... + 6 = 21 (query, key) pairs per head.
  std::vector<float> q(6 * 8, 0.1f), out(6 * 8);
  AttentionArgs at;
  at.heads = 2, at.lq = at.lk = 6, at.dh = 4, at.causal = true;
  at.q = at.k = at.v = q.data();
  at.q_ld = at.k_ld = at.v_ld = at.out_ld = 8;
  at.out = out.data();
  attention(at);
  const auto p = kernel_profile();
  ASSERT_EQ(p.size(), 3u);  // no entries of the GEMMs inside the convolutions
  double conv_flop = -1, temporal_flop = -1, attention_flop = -1;
  for (const KernelProfileEntry& e : p) {
    EXPECT_EQ(e.calls, 1) << e.kernel;
    if (e.kernel.rfind("conv2d 3x3 s1 3->5 2x6x7 ", 0) == 0) conv_flop = e.flop;
    if (e.kernel.rfind("conv_temporal3 3->5 1x4x10 ", 0) == 0) temporal_flop = e.flop;
    if (e.kernel == "attention 1x2 heads lq 6 lk 6 dh 4 causal") attention_flop = e.flop;
  }
  EXPECT_EQ(conv_flop, 2.0 * 2 * 6 * 7 * 5 * 3 * 9);
  EXPECT_EQ(temporal_flop, 2.0 * 10 * 10 * 3 * 5);
  EXPECT_EQ(attention_flop, 4.0 * 2 * 4 * 21);
}

}  // namespace
}  // namespace egopd
