#pragma once
// A temporal VAE model folder with deterministic random weights (benchmarks and tests): config.json +
// diffusion_pytorch_model.safetensors holding exactly the parameters of vae_parameter_shapes(cfg).
#include <cstdint>
#include <string>

#include "core/dtype.h"
#include "vae/vae_config.h"

namespace egopd {

// Conv/linear weights uniform with variance 1/fan_in, biases and GroupNorm shifts small, GroupNorm scales near 1,
// mix factors around 0; the same seed gives the same values for every dtype (rounded to it).
void write_random_vae(const std::string& dir, const VaeConfig& cfg, DType dtype, uint64_t seed);

}  // namespace egopd
