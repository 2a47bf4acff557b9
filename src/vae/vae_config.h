#pragma once
// AutoencoderKLTemporalDecoder configuration (vae.md §1), its parameter tree (vae.md §6) and work counts.
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/config.h"
#include "core/tensor.h"

namespace egopd {

struct VaeConfig {
  int64_t in_channels = 3, out_channels = 3, latent_channels = 4, layers_per_block = 2;
  std::vector<int64_t> block_out_channels{128, 256, 512, 512};
  double scaling_factor = 0.18215;
  static constexpr int64_t kGroups = 32;  // GroupNorm groups everywhere in this model

  // Reads the diffusers fields of vae/config.json (error naming the field on anything unsupported).
  static VaeConfig from(const Config& c);
  static VaeConfig svd_xt() { return VaeConfig{}; }
  nlohmann::json to_json() const;  // diffusers config.json

  int64_t levels() const { return int64_t(block_out_channels.size()); }
  int64_t spatial_factor() const { return int64_t(1) << (levels() - 1); }
};

// Every parameter of the model with its shape, in the order of vae.md §6 (encoder, quant_conv, decoder).
std::vector<std::pair<std::string, Shape>> vae_parameter_shapes(const VaeConfig& cfg);

// Work of one call, counted from the architecture: 2 FLOP per multiply-add of every convolution (spatial and
// temporal), linear layer and attention matrix product (normalisations and element-wise ops not counted).
double vae_encode_flop(const VaeConfig& cfg, int64_t frames, int64_t height, int64_t width);
double vae_decode_flop(const VaeConfig& cfg, int64_t frames, int64_t latent_h, int64_t latent_w);

}  // namespace egopd
