// Precision::Int8 on any CPU: the scalar quantisers of packed panels (gemm_internal.h: I8Group) and the exact
// scalar micro-kernel of quad panels, which the paths without an int8 dot product use.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/kernels/gemm_internal.h"

namespace egopd::gemm_detail {

namespace {

// Largest magnitude of each lane of `len` rows, then its scale and quantising factor.
void lane_scales(const float* src, int width, int64_t len, float* scale, float* inv) {
  for (int i = 0; i < width; ++i) {
    float m = 0.0f;
    for (int64_t k = 0; k < len; ++k) m = nan_sticky_max(m, std::fabs(src[k * width + i]));
    scale[i] = i8_scale(m);
    inv[i] = i8_inverse(m);
  }
}

// A NaN (a NaN lane's scale is NaN too, so its byte is never seen) quantises to 0: float -> int of NaN is undefined.
inline int32_t quantize(float x, float inv) {
  const float r = i8_round(x, inv);
  return r == r ? int32_t(r) : 0;
}

// One group: `len` float rows at src into the region at dst (<= src in place, else apart). In place, slot (p, i)
// is written after the floats it packs were read; those of later slots sit at rows >= 4 * p of src, past every
// slot written so far. The scales and sums go last, at slot row ceil(group / 4), once every float of the group
// has been read.
template <typename Store>
void quantize_group(const float* src, float* dst, int width, int64_t len, int64_t group, Store store) {
  float scale[kMaxNR], inv[kMaxNR];
  int32_t sum[kMaxNR] = {};
  lane_scales(src, width, len, scale, inv);
  for (int64_t p = 0; p < i8_slot_rows(len); ++p)
    for (int i = 0; i < width; ++i) {
      int32_t q[4];
      for (int t = 0; t < 4; ++t) {
        const int64_t k = 4 * p + t;
        q[t] = k < len ? quantize(src[k * width + i], inv[i]) : 0;
        sum[i] += q[t];
      }
      store(dst + p * width + i, q);
    }
  float* tail = dst + i8_slot_rows(group) * width;
  std::memcpy(tail, scale, size_t(width) * sizeof(float));
  std::memcpy(tail + width, sum, size_t(width) * sizeof(int32_t));
}

}  // namespace

void quantize_i8_quads(const float* src, float* dst, int width, int64_t kc, int64_t group, bool unsigned_bytes) {
  const auto store = [unsigned_bytes](float* slot, const int32_t* q) {
    uint8_t bytes[4];
    for (int t = 0; t < 4; ++t) bytes[t] = uint8_t(q[t] + (unsigned_bytes ? 128 : 0));
    std::memcpy(slot, bytes, 4);
  };
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += group)
    quantize_group(src + k0 * width, dst + g * i8_region(width, group), width, std::min(group, kc - k0), group,
                   store);
}

template <int MR, int NR>
void microkernel_i8_portable(int64_t kc, const float* a_panel, int64_t, int64_t, const float* b_panel, float* c,
                             int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  float sum[MR][NR] = {};
  for (int64_t g = 0, k0 = 0; k0 < kc; ++g, k0 += ep.i8_group) {
    const I8Group pa(a_panel, MR, ep.i8_group, g), pb(b_panel, NR, ep.i8_group, g);
    const int8_t* a = reinterpret_cast<const int8_t*>(pa.slots);
    const int8_t* b = reinterpret_cast<const int8_t*>(pb.slots);
    int32_t acc[MR][NR] = {};
    for (int64_t p = 0; p < i8_slot_rows(std::min(ep.i8_group, kc - k0)); ++p, a += 4 * MR, b += 4 * NR)
      for (int i = 0; i < mr; ++i)
        for (int j = 0; j < nr; ++j)
          for (int t = 0; t < 4; ++t) acc[i][j] += int32_t(a[4 * i + t]) * int32_t(b[4 * j + t]);
    for (int i = 0; i < mr; ++i)
      for (int j = 0; j < nr; ++j) sum[i][j] = std::fma(float(acc[i][j]), pa.scale[i] * pb.scale[j], sum[i][j]);
  }
  // The tile's float sums, 16 columns at a time (store_tile_scalar's row stride).
  for (int j0 = 0; j0 < nr; j0 += 16) {
    float part_sum[MR * 16];
    const int n = std::min(16, nr - j0);
    for (int i = 0; i < mr; ++i)
      for (int j = 0; j < n; ++j) part_sum[i * 16 + j] = sum[i][j0 + j];
    TileEpilogue part = ep;
    if (ep.bias_col) part.bias_col = ep.bias_col + j0;
    store_tile_scalar(part_sum, c + j0, ldc, mr, n, part);
  }
}

template void microkernel_i8_portable<kMrPortable, kNrPortable>(int64_t, const float*, int64_t, int64_t, const float*,
                                                                float*, int64_t, int, int, const TileEpilogue&);
template void microkernel_i8_portable<kMrAvx512, kNrAvx512>(int64_t, const float*, int64_t, int64_t, const float*,
                                                            float*, int64_t, int, int, const TileEpilogue&);
template void microkernel_i8_portable<kMrNeon, kNrNeon>(int64_t, const float*, int64_t, int64_t, const float*,
                                                        float*, int64_t, int, int, const TileEpilogue&);

}  // namespace egopd::gemm_detail
