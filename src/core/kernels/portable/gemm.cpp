// Portable micro-kernel, tile epilogue and packing (any CPU; also what the SIMD paths fall back to for partial
// panels).
#include <algorithm>
#include <cstring>

#include "core/error.h"
#include "core/kernels/gemm_internal.h"
#include "core/kernels/temporal_wino_pack.h"

namespace egopd::gemm_detail {

namespace {

// Element idx of a buffer of dtype dt as float32 (I8 before its scale).
inline float load_elem(const void* p, DType dt, int64_t idx) {
  switch (dt) {
    case DType::F32: return static_cast<const float*>(p)[idx];
    case DType::F16: return half_to_float(static_cast<const uint16_t*>(p)[idx]);
    case DType::BF16: return bf16_to_float(static_cast<const uint16_t*>(p)[idx]);
    case DType::I8: return float(static_cast<const int8_t*>(p)[idx]);
    default: throw Error(std::string("gemm: unsupported operand dtype ") + dtype_name(dt));
  }
}

}  // namespace

void store_tile_scalar(const float* sum, float* c, int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  constexpr int NR = 16;
  for (int i = 0; i < mr; ++i) {
    float* ci = c + i * ldc;
    const float brow = ep.bias_row ? ep.bias_row[i] : 0.0f;
    for (int j = 0; j < nr; ++j) {
      float v = sum[i * NR + j];
      if (ep.load_c) v += ci[j];
      v += brow;
      if (ep.bias_col) v += ep.bias_col[j];
      v = apply_act(ep.act, v);
      if (ep.add_after) v += ci[j];
      ci[j] = v;
    }
  }
}

void microkernel_portable(int64_t kc, const float* a, int64_t a_rs, int64_t a_cs, const float* b, float* c,
                          int64_t ldc, int mr, int nr, const TileEpilogue& ep) {
  constexpr int MR = kMrPortable, NR = kNrPortable;
  float acc[MR * NR] = {};
  const float* row[MR];
  for (int i = 0; i < MR; ++i) row[i] = a + std::min(i, mr - 1) * a_rs;  // rows >= mr: computed, never stored
  for (int64_t k = 0; k < kc; ++k) {
    const float* bk = b + k * NR;
    for (int i = 0; i < MR; ++i) {
      const float ai = row[i][k * a_cs];
      for (int j = 0; j < NR; ++j) acc[i * NR + j] += ai * bk[j];
    }
  }
  store_tile_scalar(acc, c, ldc, mr, nr, ep);
}

template <int NR>
void pack_b_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int64_t kc, int nr,
                     float* dst) {
  for (int64_t k = 0; k < kc; ++k) {
    float* d = dst + k * NR;
    for (int j = 0; j < nr; ++j) {
      float v = load_elem(p, dt, trans ? j * ld + k : k * ld + j);
      d[j] = scale ? v * scale[j] : v;
    }
    for (int j = nr; j < NR; ++j) d[j] = 0.0f;
  }
}

template <int MR>
void pack_a_portable(const void* p, DType dt, int64_t ld, bool trans, const float* scale, int mr, int64_t kc,
                     float* dst) {
  for (int64_t k = 0; k < kc; ++k) {
    float* d = dst + k * MR;
    for (int i = 0; i < mr; ++i) {
      float v = load_elem(p, dt, trans ? k * ld + i : i * ld + k);
      d[i] = scale ? v * scale[i] : v;
    }
    for (int i = mr; i < MR; ++i) d[i] = 0.0f;
  }
}

template <int NR>
void pack_b_temporal_wino_portable(int m, const float* const* in, const int64_t* ld, int64_t kc, int nr, float* dst,
                                   int64_t panel_floats) {
  temporal_wino_pack<NR>(m, in, ld, kc, nr, dst, panel_floats);
}

template <int NR>
void temporal_wino_output_portable(int m, const float* prod, int64_t prod_stride, int frames, int mr, int nr,
                                   const float* bias, bool accumulate, float* dst, int64_t frame_stride,
                                   int64_t row_stride) {
  temporal_wino_out<NR>(m, prod, prod_stride, frames, mr, nr, bias, accumulate, dst, frame_stride, row_stride);
}

template void pack_b_portable<16>(const void*, DType, int64_t, bool, const float*, int64_t, int, float*);
template void pack_b_temporal_wino_portable<kNrPortable>(int, const float* const*, const int64_t*, int64_t, int, float*,
                                                        int64_t);
template void pack_b_temporal_wino_portable<kNrNeon>(int, const float* const*, const int64_t*, int64_t, int, float*,
                                                    int64_t);
template void temporal_wino_output_portable<kNrPortable>(int, const float*, int64_t, int, int, int, const float*, bool,
                                                         float*, int64_t, int64_t);
template void temporal_wino_output_portable<kNrNeon>(int, const float*, int64_t, int, int, int, const float*, bool,
                                                     float*, int64_t, int64_t);
template void pack_b_portable<32>(const void*, DType, int64_t, bool, const float*, int64_t, int, float*);
template void pack_a_portable<kMrPortable>(const void*, DType, int64_t, bool, const float*, int, int64_t, float*);
template void pack_a_portable<kMrAvx512>(const void*, DType, int64_t, bool, const float*, int, int64_t, float*);
template void pack_b_portable<kNrNeon>(const void*, DType, int64_t, bool, const float*, int64_t, int, float*);
template void pack_a_portable<kMrNeon>(const void*, DType, int64_t, bool, const float*, int, int64_t, float*);
static_assert(kNrPortable == 16 && kNrAvx2 == 16 && kNrAvx512 == 32 && kNrNeon == 12,
              "instantiate pack_b_portable for each NR");
static_assert(kMrAvx2 == kMrPortable, "instantiate pack_a_portable for each MR");

}  // namespace egopd::gemm_detail
