#include "vae/temporal_vae.h"

#include <algorithm>
#include <cstring>
#include <filesystem>

#include "core/config.h"
#include "core/error.h"

namespace egopd {

// ---------------------------------------------------------------- encoder

VaeEncoder::VaeEncoder(const WeightView& w, const VaeConfig& c)
    : cfg(c),
      conv_in(w.sub("encoder"), "conv_in", c.in_channels, c.block_out_channels[0], 3, 1, 1),
      mid_resnet0(w.sub("encoder.mid_block.resnets.0"), c.block_out_channels.back(), c.block_out_channels.back(), 1e-6f),
      mid_attention(w.sub("encoder.mid_block.attentions.0"), c.block_out_channels.back()),
      mid_resnet1(w.sub("encoder.mid_block.resnets.1"), c.block_out_channels.back(), c.block_out_channels.back(), 1e-6f),
      conv_norm_out(w.sub("encoder"), "conv_norm_out", c.block_out_channels.back(), VaeConfig::kGroups, 1e-6f),
      conv_out(w.sub("encoder"), "conv_out", c.block_out_channels.back(), 2 * c.latent_channels, 3, 1, 1),
      quant_conv(w, "quant_conv", 2 * c.latent_channels, 2 * c.latent_channels, 1, 1, 0) {
  int64_t prev = c.block_out_channels[0];
  for (int64_t i = 0; i < c.levels(); ++i) {
    const WeightView b = w.sub("encoder.down_blocks." + std::to_string(i));
    const int64_t ch = c.block_out_channels[i];
    DownBlock blk;
    for (int64_t j = 0; j < c.layers_per_block; ++j)
      blk.resnets.emplace_back(b.sub("resnets." + std::to_string(j)), j == 0 ? prev : ch, ch, 1e-6f);
    if (i + 1 < c.levels()) blk.downsampler.emplace(b.sub("downsamplers.0"), ch);
    down_blocks.push_back(std::move(blk));
    prev = ch;
  }
}

int64_t VaeEncoder::latent_size(const VaeConfig& cfg, int64_t n) {
  for (int64_t i = 0; i + 1 < cfg.levels(); ++i) n = EncoderDownsample::out_size(n);
  return n;
}

void VaeEncoder::forward_frame(const float* image, int64_t H, int64_t W, float* moments, Arena& arena) const {
  arena.reset();
  int64_t c = cfg.block_out_channels[0];
  Tensor cur = arena.take(Shape{c, H, W});
  conv_in.forward(image, 1, H, W, cur.data());
  auto run_resnet = [&](const ResnetBlock2D& r) {
    Tensor out = r.cin == r.cout ? cur : arena.take(Shape{r.cout, H, W});
    const size_t m = arena.mark();
    r.forward_frame(cur.data(), out.data(), H, W, arena.take(Shape{r.scratch_floats(H * W)}).data());
    arena.release(m);
    cur = out;
    c = r.cout;
  };
  for (const auto& blk : down_blocks) {
    for (const auto& r : blk.resnets) run_resnet(r);
    if (blk.downsampler) {
      const int64_t h2 = EncoderDownsample::out_size(H), w2 = EncoderDownsample::out_size(W);
      Tensor out = arena.take(Shape{c, h2, w2});
      const size_t m = arena.mark();
      blk.downsampler->forward_frame(cur.data(), H, W, out.data(),
                                     arena.take(Shape{blk.downsampler->scratch_floats(H, W)}).data());
      arena.release(m);
      cur = out;
      H = h2;
      W = w2;
    }
  }
  run_resnet(mid_resnet0);
  {
    const size_t m = arena.mark();
    mid_attention.forward_frame(cur.data(), H * W, arena.take(Shape{mid_attention.scratch_floats(H * W)}).data());
    arena.release(m);
  }
  run_resnet(mid_resnet1);
  Tensor act = arena.take(Shape{c, H, W});
  conv_norm_out.forward(cur.data(), act.data(), 1, 1, H * W, /*silu=*/true);
  Tensor out = arena.take(Shape{2 * cfg.latent_channels, H, W});
  conv_out.forward(act.data(), 1, H, W, out.data());
  quant_conv.forward(out.data(), 1, H, W, moments);
}

// ---------------------------------------------------------------- decoder

TemporalDecoder::TemporalDecoder(const WeightView& w, const VaeConfig& c)
    : cfg(c),
      conv_in(w, "conv_in", c.latent_channels, c.block_out_channels.back(), 3, 1, 1),
      mid_attention(w.sub("mid_block.attentions.0"), c.block_out_channels.back()),
      conv_norm_out(w, "conv_norm_out", c.block_out_channels[0], VaeConfig::kGroups, 1e-6f),
      conv_out(w, "conv_out", c.block_out_channels[0], c.out_channels, 3, 1, 1),
      time_conv_out(w, "time_conv_out", c.out_channels, c.out_channels),
      weights(w) {
  const int64_t top = c.block_out_channels.back(), n = c.levels();
  for (int64_t j = 0; j < c.layers_per_block; ++j)
    mid_resnets.emplace_back(w.sub("mid_block.resnets." + std::to_string(j)), top, top);
  int64_t prev = top;
  for (int64_t i = 0; i < n; ++i) {
    const WeightView b = w.sub("up_blocks." + std::to_string(i));
    const int64_t ch = c.block_out_channels[n - 1 - i];
    UpBlock blk;
    for (int64_t j = 0; j <= c.layers_per_block; ++j)
      blk.resnets.emplace_back(b.sub("resnets." + std::to_string(j)), j == 0 ? prev : ch, ch);
    if (i + 1 < n) blk.upsampler.emplace(b.sub("upsamplers.0"), ch);
    up_blocks.push_back(std::move(blk));
    prev = ch;
  }
}

Tensor TemporalDecoder::forward(const Tensor& z, int64_t frames) const {
  const int64_t n = z.dim(0), batch = n / frames, top = cfg.block_out_channels.back();
  int64_t H = z.dim(2), W = z.dim(3);
  const auto done = [&](const std::string& block) {
    if (release_after_use) (block.empty() ? weights : weights.sub(block)).release();
  };
  struct ReleaseBuffer {
    ~ReleaseBuffer() { release_temporal_buffer(); }  // also when a block throws
  } release_at_return;
  Tensor x(Shape{n, top, H, W});
  conv_in.forward(z.data(), n, H, W, x.data());
  done("conv_in");

  // mid block: resnets.0 -> attentions.0 -> resnets.1 (diffusers zips resnets[1:] with the single attention)
  x = mid_resnets[0].forward(std::move(x), batch, frames, H, W, nullptr, temporal_memory);
  if (mid_resnets.size() >= 2) {
    Tensor scratch(Shape{mid_attention.scratch_floats(H * W)});
    for (int64_t f = 0; f < n; ++f) mid_attention.forward_frame(x.data() + f * top * H * W, H * W, scratch.data());
    scratch = Tensor();
    x = mid_resnets[1].forward(std::move(x), batch, frames, H, W, nullptr, temporal_memory);
  }
  done("mid_block");

  // up blocks; an upsampler is fused into the first res-block after it (the upsampled clip is never stored), so its
  // block's weights are released after that res-block
  const Upsample2x* pending = nullptr;
  for (size_t i = 0; i < up_blocks.size(); ++i) {
    const UpBlock& blk = up_blocks[i];
    for (const auto& r : blk.resnets) {
      if (pending) H *= 2, W *= 2, release_temporal_buffer();  // a larger level: no peak with the last one's
      x = r.forward(std::move(x), batch, frames, H, W, pending, temporal_memory);
      if (pending) done("up_blocks." + std::to_string(i - 1));
      pending = nullptr;
    }
    if (blk.upsampler) pending = &*blk.upsampler;
    else done("up_blocks." + std::to_string(i));
  }
  EGOPD_CHECK(pending == nullptr, "the last decoder up block has no upsampler");

  // conv_norm_out -> SiLU -> conv_out per frame, then time_conv_out over the frames of each video
  const int64_t c0 = cfg.block_out_channels[0], co = cfg.out_channels, hw = H * W;
  Tensor frames_out(Shape{n, co, H, W});
  {
    Tensor act(Shape{c0, H, W});
    for (int64_t f = 0; f < n; ++f) {
      conv_norm_out.forward(x.data() + f * c0 * hw, act.data(), 1, 1, hw, /*silu=*/true);
      conv_out.forward(act.data(), 1, H, W, frames_out.data() + f * co * hw);
    }
  }
  x = Tensor();
  Tensor y(Shape{n, co, H, W});
  time_conv_out.forward(frames_out.data(), batch, frames, hw, y.data());  // R5 -> Conv3d (3,1,1) -> R5⁻¹
  done("");
  return y;
}

// ---------------------------------------------------------------- TemporalVAE

TemporalVAE::TemporalVAE(const std::string& dir) {
  cfg_ = VaeConfig::from(Config::load((std::filesystem::path(dir) / "config.json").string()));
  weights_ = WeightMap::load_dir(dir, "diffusion_pytorch_model", "vae");
  encoder_ = std::make_unique<VaeEncoder>(weights_.root(), cfg_);
  decoder_ = std::make_unique<TemporalDecoder>(weights_.root().sub("decoder"), cfg_);
  weights_.check_all_used({});
}

Tensor TemporalVAE::encode_mean(const Tensor& images, Tensor* logvar) const {
  if (images.ndim() != 4 || images.dim(1) != cfg_.in_channels || images.dim(2) < 1 || images.dim(3) < 1)
    throw Error("vae encode: images must be [N, " + std::to_string(cfg_.in_channels) + ", H, W], got " +
                images.shape().str());
  const int64_t n = images.dim(0), H = images.dim(2), W = images.dim(3), lc = cfg_.latent_channels;
  const int64_t h = VaeEncoder::latent_size(cfg_, H), w = VaeEncoder::latent_size(cfg_, W);
  if (h < 1 || w < 1) throw Error("vae encode: images of " + std::to_string(H) + "x" + std::to_string(W) +
                                  " are too small for " + std::to_string(cfg_.levels() - 1) + " downsamplings");
  Tensor mean(Shape{n, lc, h, w});
  if (logvar) *logvar = Tensor(Shape{n, lc, h, w});
  Tensor moments(Shape{2 * lc, h, w});
  Arena arena;
  const int64_t plane = lc * h * w;
  for (int64_t f = 0; f < n; ++f) {
    encoder_->forward_frame(images.data() + f * cfg_.in_channels * H * W, H, W, moments.data(), arena);
    // moments [2·latent, h, w] -> mean = [0, latent), logvar = clamp([latent, 2·latent), -30, 20)
    std::memcpy(mean.data() + f * plane, moments.data(), size_t(plane) * sizeof(float));
    if (logvar)
      for (int64_t i = 0; i < plane; ++i) (*logvar)[f * plane + i] = std::clamp(moments[plane + i], -30.0f, 20.0f);
  }
  return mean;
}

namespace {

void check_latents(const Tensor& z, int64_t latent_channels, int64_t num_frames) {
  if (z.ndim() != 4 || z.dim(1) != latent_channels || z.dim(0) < 1 || z.dim(2) < 1 || z.dim(3) < 1)
    throw Error("vae decode: latents must be [B*F, " + std::to_string(latent_channels) + ", h, w], got " +
                z.shape().str());
  if (num_frames < 1 || z.dim(0) % num_frames != 0)
    throw Error("vae decode: " + std::to_string(z.dim(0)) + " latent rows are not a whole number of videos of " +
                std::to_string(num_frames) + " frames");
}

}  // namespace

Tensor TemporalVAE::decode_frames(const Tensor& z, int64_t num_frames) const {
  check_latents(z, cfg_.latent_channels, num_frames);
  return decoder_->forward(z, num_frames);
}

Tensor TemporalVAE::decode(const Tensor& z, int64_t num_frames, int64_t chunk) const {
  check_latents(z, cfg_.latent_channels, num_frames);
  const int64_t n = z.dim(0);
  if (chunk <= 0) chunk = num_frames;
  if (chunk >= n) return decode_frames(z, n);  // one chunk: the whole batch as one sequence
  const int64_t row = z.numel() / n;
  Tensor out;
  for (int64_t r0 = 0; r0 < n; r0 += chunk) {
    const int64_t rows = std::min(chunk, n - r0);
    Tensor part(Shape{rows, z.dim(1), z.dim(2), z.dim(3)});
    std::memcpy(part.data(), z.data() + r0 * row, size_t(rows * row) * sizeof(float));
    Tensor y = decoder_->forward(part, rows);  // one sequence of `rows` frames (batch 1)
    if (out.empty()) out = Tensor(Shape{n, y.dim(1), y.dim(2), y.dim(3)});
    std::memcpy(out.data() + r0 * (y.numel() / rows), y.data(), size_t(y.numel()) * sizeof(float));
  }
  return out;
}

Tensor TemporalVAE::decode_latents(const Tensor& latents, int64_t num_frames, int64_t chunk) const {
  const float inv = float(1.0 / cfg_.scaling_factor);  // the reference multiplies by the float32 reciprocal
  Tensor z(latents.shape());
  for (int64_t i = 0; i < z.numel(); ++i) z[i] = latents[i] * inv;
  return decode(z, num_frames, chunk);
}

}  // namespace egopd
