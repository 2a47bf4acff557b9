#pragma once
// `egopd-convert dtype`: re-store every weight file of a model directory (or one file) as F32, F16, BF16 or q8.
// q8 = per-output-channel symmetric int8 for linear and conv weights: `<key>` I8 + `<key>_scale` F32 [rows]
// (the runtime's WeightView::get reads exactly this); everything else keeps its float dtype.
#include <cstdint>
#include <string>
#include <vector>

#include "convert/tensor_io.h"

namespace egopd {

enum class TargetDType { F32, F16, BF16, Q8 };
TargetDType parse_target_dtype(const std::string& s);  // "f32" | "f16" | "bf16" | "q8"; error otherwise

// Linear / conv weights: "<...>.weight" of rank >= 2 that is not an embedding table (token / position embeddings).
bool is_q8_quantizable(const std::string& key, const std::vector<int64_t>& shape);

// Row r of the [rows, cols] matrix w: scale[r] = max|w_r| / 127 and q = round-half-to-even(w / scale[r]) clamped
// to [-127, 127]; an all-zero row gets scale 0 and q = 0 (no division).
void quantize_rows_q8(const float* w, int64_t rows, int64_t cols, int8_t* q, float* scale);

struct DTypeReport {
  size_t files = 0, tensors = 0, quantized = 0, copied_files = 0;
  uint64_t bytes_in = 0, bytes_out = 0;
};

// `in`: a model directory (every folder's weight files converted, other files copied) or one .safetensors /
// .safetensors.index.json. `out` must differ from `in`.
DTypeReport convert_dtype(const std::string& in, const std::string& out, TargetDType to, const WriteOptions& write);

// The converted tensors of one weight map (sorted by name), for writing with write_weights.
std::vector<OutTensor> converted_tensors(const WeightMap& w, TargetDType to, DTypeReport* report);

}  // namespace egopd
