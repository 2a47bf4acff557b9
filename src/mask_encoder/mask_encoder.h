#pragma once
// Mask encoder (egopressurediff.md §2): diffusers ControlNetConditioningEmbedding turning binary hand masks
// [F, 1, S, S] into features Mf [F, 8, S/8, S/8] that are added to the U-Net input at every step.
#include <memory>
#include <string>
#include <vector>

#include "core/config.h"
#include "core/layers.h"
#include "core/weights.h"

namespace egopd {

struct MaskEncoderConfig {
  int64_t conditioning_channels = 1;
  std::vector<int64_t> block_out_channels{16, 32, 96, 256};
  int64_t conditioning_embedding_channels = 8;
  static MaskEncoderConfig from(const Config& c);
  static MaskEncoderConfig load(const std::string& dir);
  int64_t downscale() const { return int64_t(1) << (block_out_channels.size() - 1); }
};

class MaskEncoder {
 public:
  explicit MaskEncoder(const std::string& dir);  // mask_encoder/: config.json + diffusion_pytorch_model.safetensors
  MaskEncoder(const MaskEncoderConfig& config, std::shared_ptr<const WeightMap> weights);
  const MaskEncoderConfig& config() const { return cfg_; }
  // masks [F, conditioning_channels, S, S] -> [F, conditioning_embedding_channels, S/d, S/d]
  Tensor forward(const Tensor& masks) const;

 private:
  MaskEncoderConfig cfg_;
  std::shared_ptr<const WeightMap> weights_;
  Conv2d conv_in_, conv_out_;
  std::vector<Conv2d> blocks_;
};

}  // namespace egopd
