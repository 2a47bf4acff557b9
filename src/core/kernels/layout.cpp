#include "core/kernels/layout.h"

#include <algorithm>

#include "core/cpu.h"

namespace egopd {

#if defined(__x86_64__)
// The SIMD block kernels (avx2/layout.cpp, avx512/layout.cpp): d[c * ldd + r] (+)= s[r * lds + c].
namespace avx2 {
void transpose_block(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols, bool add);
}
namespace avx512 {
void transpose_block(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols, bool add);
}
#endif

namespace {

void transpose_block_portable(const float* s, int64_t lds, float* d, int64_t ldd, int64_t rows, int64_t cols,
                              bool add) {
  for (int64_t r = 0; r < rows; ++r)
    for (int64_t c = 0; c < cols; ++c) {
      float* dst = d + c * ldd + r;
      *dst = add ? *dst + s[r * lds + c] : s[r * lds + c];
    }
}

using TransposeBlock = void (*)(const float*, int64_t, float*, int64_t, int64_t, int64_t, bool);

TransposeBlock transpose_block_kernel() {
#if defined(__x86_64__)
  if (kernel_path() == KernelPath::Avx512) return avx512::transpose_block;
  if (kernel_path() == KernelPath::Avx2) return avx2::transpose_block;
#endif
  return transpose_block_portable;  // and NEON: the compiler's loops
}

// 32x32 blocks, so both sides of a block stay in L1.
void transpose_tiles(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols, bool add) {
  constexpr int64_t T = 32;
  const TransposeBlock block = transpose_block_kernel();
#pragma omp parallel for collapse(2) schedule(static) if (batch * rows * cols > 32768)
  for (int64_t b = 0; b < batch; ++b) {
    for (int64_t r0 = 0; r0 < rows; r0 += T) {
      const float* s = src + b * rows * cols;
      float* d = dst + b * rows * cols;
      const int64_t nr = std::min(T, rows - r0);
      for (int64_t c0 = 0; c0 < cols; c0 += T)
        block(s + r0 * cols + c0, cols, d + c0 * rows + r0, rows, nr, std::min(T, cols - c0), add);
    }
  }
}

}  // namespace

void transpose_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols) {
  transpose_tiles(src, dst, batch, rows, cols, false);
}

void transpose_add_batched(const float* src, float* dst, int64_t batch, int64_t rows, int64_t cols) {
  transpose_tiles(src, dst, batch, rows, cols, true);
}

// [B*F, L, C] <-> [B*L, F, C]: both are row copies of C floats.
void frames_to_sequences(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c) {
#pragma omp parallel for collapse(2) schedule(static)
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t li = 0; li < l; ++li)
      for (int64_t fi = 0; fi < f; ++fi)
        std::copy_n(src + ((bi * f + fi) * l + li) * c, c, dst + ((bi * l + li) * f + fi) * c);
}

void sequences_to_frames(const float* src, float* dst, int64_t b, int64_t f, int64_t l, int64_t c) {
#pragma omp parallel for collapse(2) schedule(static)
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t fi = 0; fi < f; ++fi)
      for (int64_t li = 0; li < l; ++li)
        std::copy_n(src + ((bi * l + li) * f + fi) * c, c, dst + ((bi * f + fi) * l + li) * c);
}

}  // namespace egopd
