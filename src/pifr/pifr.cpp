#include "pifr/pifr.h"

#include <algorithm>

#include "core/kernels/elementwise.h"

namespace egopd {

Pifr::Pifr(const WeightView& w, int64_t c, int64_t heads, int64_t text_dim) : channels(c) {
  attn_text = Attention(w.sub("attn_text"), c, text_dim, heads, c / heads, /*qkv_bias=*/false);
  mod = Linear(w, "mod.1", c, 2 * c, true);
}

ContextCache Pifr::prepare_text(const float* text, int64_t videos, int64_t tokens) const {
  return attn_text.prepare_context(text, videos, tokens);
}

void Pifr::apply(const float* n, int64_t rows, int64_t rows_per_video, const Attention& attn2,
                 const ContextCache& proto, const ContextCache* text, float* x, Arena& arena) const {
  const int64_t C = channels;
  const size_t mark = arena.mark();
  // z_proto [rows, C]; with one prototype token it is one vector per video, read in place.
  const float* zp = nullptr;
  int64_t zp_rows_per_vec = 1;
  Tensor zp_full;
  if (proto.is_folded()) {
    zp = proto.folded.data();
    zp_rows_per_vec = rows_per_video;
  } else {
    zp_full = arena.take({rows, C});
    attn2.cross_attention(n, rows, rows_per_video, proto, zp_full.data(), false, arena);
    zp = zp_full.data();
  }
  // m [rows, 2C] = mod(SiLU(z_text)); without text z_text = 0 so m = mod.bias for every row.
  Tensor m;
  int64_t m_rows_per_vec = 1;
  if (text) {
    m = arena.take({rows, 2 * C});
    Tensor zt = arena.take({rows, C});
    attn_text.cross_attention(n, rows, rows_per_video, *text, zt.data(), false, arena);
    silu_inplace(zt.data(), rows * C);
    mod.forward(zt.data(), rows, m.data());
  } else {
    m = mod.bias;
    m_rows_per_vec = rows;
  }
  const float* mp = m.data();
#pragma omp parallel for schedule(static) if (rows * C > 65536)
  for (int64_t r = 0; r < rows; ++r) {
    const float* z = zp + (r / zp_rows_per_vec) * C;
    const float* g = mp + (r / m_rows_per_vec) * 2 * C;
    const float* b = g + C;
    float* xr = x + r * C;
    for (int64_t j = 0; j < C; ++j) xr[j] += z[j] * (1.0f + g[j]) + b[j];
  }
  arena.release(mark);
}

}  // namespace egopd
