#pragma once
// UNetSpatioTemporalConditionModel, the SVD-xt denoiser (unet3d.md), with the optional PIFR layers of
// EgoPressureDiff. Construction loads and checks every weight; prepare() computes everything that depends only on
// the conditioning (cross-attention keys/values, the folded single-token attentions, PIFR text keys/values) once
// per run; forward() is one denoiser evaluation.
#include <memory>
#include <string>
#include <vector>

#include "core/layers.h"
#include "core/timing.h"
#include "core/weights.h"
#include "unet3d/resblock.h"
#include "unet3d/transformer.h"
#include "unet3d/unet_config.h"

namespace egopd {

struct UNetConditioning {
  int64_t videos = 0;
  std::vector<TransformerConditioning> transformers;  // in execution order
};

class UNetSpatioTemporal {
 public:
  // unet/ folder: config.json + diffusion_pytorch_model.safetensors (or sharded / variant).
  explicit UNetSpatioTemporal(const std::string& dir);
  UNetSpatioTemporal(const UNetConfig& config, std::shared_ptr<const WeightMap> weights);

  const UNetConfig& config() const { return cfg_; }
  // ehs [B, S, cross_dim] (S = 1 in SVD: the prototype / image token); text [B, T, text_dim] or null (no text).
  UNetConditioning prepare(const Tensor& ehs, const Tensor* text) const;
  // sample [B, F, in_channels, h, w], timestep (c_noise, broadcast over B), added_time_ids [B, 3]
  // -> v-prediction [B, F, out_channels, h, w]
  Tensor forward(const Tensor& sample, float timestep, const Tensor& added_time_ids, const UNetConditioning& cond);

  // Work of one evaluation in FLOPs (multiply-add = 2) counted from the config: `total` as PyTorch runs it,
  // `executed` without the single-token cross-attentions that folding removes (their once-per-run cost excluded).
  struct Flops {
    double total = 0, executed = 0;
  };
  Flops flops(int64_t videos, int64_t frames, int64_t h, int64_t w, int64_t context_tokens, int64_t text_tokens) const;
  // Attach a per-block-type time breakdown (null: off).
  void set_profile(StageTimes* times) { profile_ = times; }
  const std::shared_ptr<const WeightMap>& weights() const { return weights_; }
  // Low-memory mode: forward() drops the mapped pages of each res-block's and transformer's weights once it has run
  // (WeightMap::release), so about one layer's weights are resident at a time; the next step reads them again.
  void set_release_weights_after_use(bool on) { release_after_use_ = on; }

 private:
  struct DownBlock {
    std::vector<SpatioTemporalResBlock> resnets;
    std::vector<TransformerSpatioTemporal> attentions;  // empty for DownBlockSpatioTemporal
    bool has_downsampler = false;
    Conv2d downsampler;
  };
  struct UpBlock {
    std::vector<SpatioTemporalResBlock> resnets;
    std::vector<TransformerSpatioTemporal> attentions;
    bool has_upsampler = false;
    Conv2d upsampler;
  };
  void build();

  UNetConfig cfg_;
  std::shared_ptr<const WeightMap> weights_;
  Conv2d conv_in_, conv_out_;
  Linear time_linear_1_, time_linear_2_, add_linear_1_, add_linear_2_;
  GroupNorm norm_out_;
  std::vector<DownBlock> down_;
  SpatioTemporalResBlock mid_res0_, mid_res1_;
  TransformerSpatioTemporal mid_attn_;
  std::vector<UpBlock> up_;
  Arena arena_;
  StageTimes* profile_ = nullptr;
  bool release_after_use_ = false;
};

}  // namespace egopd
