#pragma once
// AutoencoderKLTemporalDecoder (the SVD VAE, vae.md): per-frame KL encoder + quant_conv, and the temporal decoder.
//   TemporalVAE vae(dir);                                   // dir: config.json + diffusion_pytorch_model.safetensors
//   Tensor mean = vae.encode_mean(frames);                  // [N,3,H,W] in [-1,1] -> [N,4,H/8,W/8], unscaled
//   Tensor rgb = vae.decode_latents(latents, F);            // x·(1/0.18215), chunks of F rows -> [N,3,H,W]
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "core/layers.h"
#include "core/tensor.h"
#include "core/weights.h"
#include "vae/vae_blocks.h"
#include "vae/vae_config.h"

namespace egopd {

// Encoder (vae.md §3): purely 2-D, run one frame at a time.
struct VaeEncoder {
  struct DownBlock {
    std::vector<ResnetBlock2D> resnets;
    std::optional<EncoderDownsample> downsampler;
  };
  VaeConfig cfg;
  Conv2d conv_in;
  std::vector<DownBlock> down_blocks;
  ResnetBlock2D mid_resnet0;
  MidBlockAttention mid_attention;
  ResnetBlock2D mid_resnet1;
  GroupNorm conv_norm_out;
  Conv2d conv_out;
  Conv2d quant_conv;

  // w: the model root (encoder.* and quant_conv.*).
  VaeEncoder(const WeightView& w, const VaeConfig& cfg);
  // One frame: image [in, H, W] -> moments [2·latent, h, w]. Activations live in `arena` (reset here).
  void forward_frame(const float* image, int64_t H, int64_t W, float* moments, Arena& arena) const;
  static int64_t latent_size(const VaeConfig& cfg, int64_t n);
};

// TemporalDecoder (vae.md §4).
struct TemporalDecoder {
  struct UpBlock {
    std::vector<VaeSpatioTemporalResBlock> resnets;
    std::optional<Upsample2x> upsampler;
  };
  VaeConfig cfg;
  Conv2d conv_in;
  std::vector<VaeSpatioTemporalResBlock> mid_resnets;  // layers_per_block of them; only 0 and 1 ever run
  MidBlockAttention mid_attention;                  // runs between mid_resnets 0 and 1 (not at all if there is no 1)
  std::vector<UpBlock> up_blocks;
  GroupNorm conv_norm_out;
  Conv2d conv_out;
  TemporalConv3 time_conv_out;
  TemporalMemory temporal_memory;  // how the temporal halves trade memory for time
  WeightView weights;              // decoder.*, for paging a block out after it runs
  bool release_after_use = false;  // low-memory mode: only the running block's weights stay resident

  TemporalDecoder(const WeightView& w, const VaeConfig& cfg);  // w: decoder.*
  // diffusers TemporalDecoder(z, num_frames): z [batch·frames, latent, h, w] (frame-major videos of `frames` frames)
  // -> [batch·frames, out, h·8, w·8].
  Tensor forward(const Tensor& z, int64_t frames) const;
};

class TemporalVAE {
 public:
  // Loads config.json and the weights (F32/F16/BF16); every tensor is shape-checked and any tensor the architecture
  // does not use is an error.
  explicit TemporalVAE(const std::string& dir);
  TemporalVAE(const TemporalVAE&) = delete;
  TemporalVAE& operator=(const TemporalVAE&) = delete;

  const VaeConfig& config() const { return cfg_; }
  float scaling_factor() const { return float(cfg_.scaling_factor); }
  uint64_t weight_bytes() const { return weights_.total_bytes(); }
  // How the decoder's temporal halves trade speed for memory (pixel tiles, conv1 recomputation); no effect on the
  // result beyond float rounding order.
  void set_temporal_memory(const TemporalMemory& mem) { decoder_->temporal_memory = mem; }
  // Low-memory mode: the decoder pages each block's weights out after it runs (WeightMap::release); they are read
  // again from the file on the next decode.
  void set_release_weights_after_use(bool on) { decoder_->release_after_use = on; }

  // images [N, in, H, W] -> posterior mean (= mode()) [N, latent, H/8, W/8]; logvar, if asked, clamped to [-30, 20].
  // No scaling factor.
  Tensor encode_mean(const Tensor& images, Tensor* logvar = nullptr) const;

  // The decoder called directly, as diffusers' decode(z, num_frames): z [B·F, latent, h, w] is B videos of
  // num_frames frames each (temporal layers couple the frames of each video). No scaling.
  Tensor decode_frames(const Tensor& z, int64_t num_frames) const;

  // Chunked decoding (vae.md §5.2): consecutive chunks of `chunk` rows (<= 0: num_frames), each decoded as ONE
  // sequence of its rows, even when a chunk spans two videos; the result depends on the chunk size. No scaling.
  Tensor decode(const Tensor& z, int64_t num_frames, int64_t chunk = 0) const;

  // vae.md §5: z · float32(1/scaling_factor), then decode(…, num_frames, chunk).
  Tensor decode_latents(const Tensor& latents, int64_t num_frames, int64_t chunk = 0) const;

 private:
  VaeConfig cfg_;
  WeightMap weights_;
  std::unique_ptr<VaeEncoder> encoder_;
  std::unique_ptr<TemporalDecoder> decoder_;
};

}  // namespace egopd
