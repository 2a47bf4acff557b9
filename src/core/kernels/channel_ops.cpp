#include "core/kernels/channel_ops.h"

#include <algorithm>
#include <cstring>

namespace egopd {

void add_frame_channel_bias(float* x, int64_t n, int64_t c, int64_t s, const float* bias) {
#pragma omp parallel for collapse(2) schedule(static) if (n * c * s > 65536)
  for (int64_t i = 0; i < n; ++i)
    for (int64_t j = 0; j < c; ++j) {
      float* p = x + (i * c + j) * s;
      const float b = bias[i * c + j];
      for (int64_t k = 0; k < s; ++k) p[k] += b;
    }
}

void concat_channels(const float* a, int64_t c1, const float* b, int64_t c2, int64_t n, int64_t s, float* out) {
#pragma omp parallel for schedule(static) if (n * (c1 + c2) * s > 65536)
  for (int64_t i = 0; i < n; ++i) {
    std::memcpy(out + i * (c1 + c2) * s, a + i * c1 * s, size_t(c1 * s) * sizeof(float));
    std::memcpy(out + (i * (c1 + c2) + c1) * s, b + i * c2 * s, size_t(c2 * s) * sizeof(float));
  }
}

void add_row_vectors(float* x, int64_t rows, int64_t c, const float* v, int64_t rows_per_vec) {
#pragma omp parallel for schedule(static) if (rows * c > 65536)
  for (int64_t r = 0; r < rows; ++r) {
    const float* vr = v + (r / rows_per_vec) * c;
    float* xr = x + r * c;
    for (int64_t j = 0; j < c; ++j) xr[j] += vr[j];
  }
}

}  // namespace egopd
