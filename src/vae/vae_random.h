#pragma once
// A temporal VAE model folder with deterministic random weights (benchmarks and tests): config.json +
// diffusion_pytorch_model.safetensors holding exactly the parameters of vae_parameter_shapes(cfg), with the values
// of core/synthetic_weights.h.
#include <cstdint>
#include <string>

#include "core/dtype.h"
#include "vae/vae_config.h"

namespace egopd {

void write_random_vae(const std::string& dir, const VaeConfig& cfg, DType dtype, uint64_t seed);

}  // namespace egopd
