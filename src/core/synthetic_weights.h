#pragma once
// Deterministic random weights for a parameter list (from WeightMap::recorder()), streamed to a safetensors file.
// Values: U(-1/sqrt(fan_in), 1/sqrt(fan_in)) for matrices and kernels (PyTorch's default bound), 1 for 1-D norm
// weights, small uniform biases, 0 for AlphaBlender mix factors. Each tensor's values depend only on the seed and
// its name, so sharding or reordering does not change them.
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/dtype.h"
#include "core/tensor.h"

namespace egopd {

void write_synthetic_safetensors(const std::string& path, const std::vector<std::pair<std::string, Shape>>& params,
                                 DType dtype, uint64_t seed);

// Sixteen hex digits that identify the file write_synthetic_safetensors writes for these arguments (a hash of every
// name and shape, the dtype, the seed and the values the generator gives for a few probes): a cache key, so that a
// cached file is never reused for other parameters or by a build whose generator writes other values.
std::string synthetic_weights_id(const std::vector<std::pair<std::string, Shape>>& params, DType dtype,
                                 uint64_t seed);

// The float32 values write_synthetic_safetensors stores (before rounding to dtype), for one parameter.
void synthetic_values(const std::string& name, const Shape& shape, uint64_t seed, float* out);

}  // namespace egopd
