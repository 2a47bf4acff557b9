// Convolutions (simple portable version: im2col per frame + gemm; the implicit-GEMM version replaces it).
#include "core/kernels/conv.h"

#include <vector>

#include "core/error.h"

namespace egopd {

void conv2d(const float* x, int64_t n, int64_t h, int64_t w, const Operand& weight, const float* bias,
            const Conv2dGeom& g, float* y, Act act, bool accumulate) {
  const int64_t oh = g.out_h(h), ow = g.out_w(w), ohw = oh * ow;
  const int64_t K = g.cin * g.kh * g.kw;
  std::vector<float> col(size_t(K) * ohw);
  Operand wa = weight;
  wa.trans = false;
  wa.ld = K;
  Epilogue ep{bias, true, act, accumulate};
  for (int64_t f = 0; f < n; ++f) {
    const float* xf = x + f * g.cin * h * w;
    // [cin, h, w] -> col [cin*kh*kw, oh*ow]
    for (int64_t c = 0; c < g.cin; ++c)
      for (int64_t ky = 0; ky < g.kh; ++ky)
        for (int64_t kx = 0; kx < g.kw; ++kx) {
          float* row = &col[((c * g.kh + ky) * g.kw + kx) * ohw];
          for (int64_t oy = 0; oy < oh; ++oy)
            for (int64_t ox = 0; ox < ow; ++ox) {
              int64_t iy = oy * g.stride_h - g.pad_h + ky, ix = ox * g.stride_w - g.pad_w + kx;
              row[oy * ow + ox] = (iy >= 0 && iy < h && ix >= 0 && ix < w) ? xf[(c * h + iy) * w + ix] : 0.0f;
            }
        }
    gemm(g.cout, ohw, K, wa, f32_operand(col.data(), ohw), y + f * g.cout * ohw, ohw, ep);
  }
}

void conv_temporal3(const float* x, int64_t b, int64_t f, int64_t cin, int64_t hw, const Operand& weight,
                    const float* bias, int64_t cout, float* y, Act act, bool accumulate) {
  // Per tap k: y[b,t] += W[:,:,k] · x[b,t+k-1]; the weight [cout, cin, 3] seen with column stride 3.
  // Simple version: gather the tap matrix, then three gemms (the first one carries bias, the last the epilogue).
  std::vector<float> tmp(size_t(cout) * hw);
  const size_t esize = dtype_size(weight.dtype);
  for (int64_t bi = 0; bi < b; ++bi)
    for (int64_t t = 0; t < f; ++t) {
      std::fill(tmp.begin(), tmp.end(), 0.0f);
      for (int k = 0; k < 3; ++k) {
        int64_t ts = t + k - 1;
        if (ts < 0 || ts >= f) continue;
        // Weight tap k: element (o, c) at o*3*cin + c*3 + k; no stride in Operand, so gather it.
        std::vector<float> wk(size_t(cout) * cin);
        for (int64_t o = 0; o < cout; ++o)
          for (int64_t c = 0; c < cin; ++c) {
            const char* p = static_cast<const char*>(weight.data) + size_t(o * 3 * cin + c * 3 + k) * esize;
            float v;
            switch (weight.dtype) {
              case DType::F32: v = *reinterpret_cast<const float*>(p); break;
              case DType::F16: v = half_to_float(*reinterpret_cast<const uint16_t*>(p)); break;
              case DType::BF16: v = bf16_to_float(*reinterpret_cast<const uint16_t*>(p)); break;
              case DType::I8: v = float(*reinterpret_cast<const int8_t*>(p)) * weight.scale[o]; break;
              default: throw Error("conv_temporal3: unsupported weight dtype");
            }
            wk[o * cin + c] = v;
          }
        Epilogue ep{nullptr, true, Act::None, true};
        gemm(cout, hw, cin, f32_operand(wk.data(), cin), f32_operand(x + (bi * f + ts) * cin * hw, hw), tmp.data(),
             hw, ep);
      }
      float* yo = y + (bi * f + t) * cout * hw;
      for (int64_t o = 0; o < cout; ++o)
        for (int64_t p = 0; p < hw; ++p) {
          float v = apply_act(act, tmp[o * hw + p] + (bias ? bias[o] : 0.0f));
          yo[o * hw + p] = accumulate ? yo[o * hw + p] + v : v;
        }
    }
}

}  // namespace egopd
