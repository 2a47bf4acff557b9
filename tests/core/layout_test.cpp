// Re-layouts (unet3d.md §2) against index formulas written out directly.
#include "core/kernels/layout.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <tuple>
#include <vector>

#include "core/cpu.h"
#include "core/kernel_reference.h"

namespace egopd {
namespace {

std::vector<float> iota_values(int64_t n) {
  std::vector<float> v(n);
  for (int64_t i = 0; i < n; ++i) v[i] = static_cast<float>(i) * 0.25f - 7.0f;
  return v;
}

// Every kernel path (8x8 and 16x16 register blocks inside 32x32 cache blocks): edges of 1, 7, 15, 17 and 31.
TEST(Layout, TransposeBatched) {
  for (KernelPath path : supported_kernel_paths())
    for (auto [batch, rows, cols] : {std::tuple<int64_t, int64_t, int64_t>{1, 1, 1}, {2, 1, 9}, {3, 7, 1},
                                     {3, 33, 65}, {2, 320, 64}, {1, 64, 1024}, {2, 15, 17}, {1, 16, 16},
                                     {1, 31, 47}, {2, 49, 40}}) {
      test::KernelPathGuard guard(path);
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " batch=" << batch << " rows=" << rows
                                      << " cols=" << cols);
      const std::vector<float> src = iota_values(batch * rows * cols);
      std::vector<float> dst(src.size(), -1.0f), back(src.size(), -1.0f);
      transpose_batched(src.data(), dst.data(), batch, rows, cols);
      for (int64_t b = 0; b < batch; ++b)
        for (int64_t r = 0; r < rows; ++r)
          for (int64_t c = 0; c < cols; ++c)
            ASSERT_EQ(dst[(b * cols + c) * rows + r], src[(b * rows + r) * cols + c]) << b << "," << r << "," << c;
      transpose_batched(dst.data(), back.data(), batch, cols, rows);
      EXPECT_EQ(back, src);
    }
}

TEST(Layout, FramesToSequencesAndBack) {
  for (auto [b, f, l, c] : {std::tuple<int64_t, int64_t, int64_t, int64_t>{1, 1, 1, 1}, {1, 1, 5, 3}, {2, 3, 5, 7},
                            {1, 16, 64, 40}, {2, 14, 9, 1}}) {
    SCOPED_TRACE(testing::Message() << "b=" << b << " f=" << f << " l=" << l << " c=" << c);
    const std::vector<float> t = iota_values(b * f * l * c);
    std::vector<float> s(t.size(), -1.0f), back(t.size(), -1.0f);
    frames_to_sequences(t.data(), s.data(), b, f, l, c);
    // s[b*L + l, f, :] = t[b*F + f, l, :]
    for (int64_t bi = 0; bi < b; ++bi)
      for (int64_t fi = 0; fi < f; ++fi)
        for (int64_t li = 0; li < l; ++li)
          for (int64_t ci = 0; ci < c; ++ci)
            ASSERT_EQ(s[((bi * l + li) * f + fi) * c + ci], t[((bi * f + fi) * l + li) * c + ci]);
    sequences_to_frames(s.data(), back.data(), b, f, l, c);
    EXPECT_EQ(back, t);
  }
}

TEST(Layout, TransposeAddOntoResidual) {
  for (KernelPath path : supported_kernel_paths())
    for (auto [batch, rows, cols] : {std::tuple<int64_t, int64_t, int64_t>{1, 1, 1}, {2, 33, 7}, {3, 64, 40},
                                     {1, 1, 65}, {2, 17, 15}, {1, 47, 31}, {1, 256, 320}}) {
      test::KernelPathGuard guard(path);
      SCOPED_TRACE(testing::Message() << kernel_path_name(path) << " " << batch << "x" << rows << "x" << cols);
      const std::vector<float> src = iota_values(batch * rows * cols);
      std::vector<float> dst(src.size());
      for (size_t i = 0; i < dst.size(); ++i) dst[i] = 0.5f * float(i % 13) - 3.0f;
      const std::vector<float> before = dst;
      transpose_add_batched(src.data(), dst.data(), batch, rows, cols);
      for (int64_t b = 0; b < batch; ++b)
        for (int64_t r = 0; r < rows; ++r)
          for (int64_t c = 0; c < cols; ++c) {
            const int64_t d = (b * cols + c) * rows + r;
            ASSERT_EQ(dst[d], before[d] + src[(b * rows + r) * cols + c]);
          }
    }
}

}  // namespace
}  // namespace egopd
