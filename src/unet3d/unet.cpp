#include "unet3d/unet.h"

#include <cstring>
#include <optional>

#include "core/error.h"
#include "core/kernels/channel_ops.h"
#include "core/kernels/elementwise.h"

namespace egopd {

UNetSpatioTemporal::UNetSpatioTemporal(const std::string& dir)
    : UNetSpatioTemporal(UNetConfig::load(dir), std::make_shared<WeightMap>(
                                                    WeightMap::load_dir(dir, "diffusion_pytorch_model", "unet"))) {}

UNetSpatioTemporal::UNetSpatioTemporal(const UNetConfig& config, std::shared_ptr<const WeightMap> weights)
    : cfg_(config), weights_(std::move(weights)) {
  build();
  // Strict loading: every stored tensor must belong to the configured architecture (PIFR keys are ignored when
  // PIFR is disabled).
  std::vector<std::string> tolerated;
  if (!cfg_.pifr_enabled) tolerated.push_back(".pifr.");
  weights_->check_all_used(tolerated);
}

void UNetSpatioTemporal::build() {
  const WeightView w = weights_->root();
  const auto& ch = cfg_.block_out_channels;
  const int64_t n = cfg_.blocks(), ted = cfg_.time_embed_dim();
  const int64_t text_dim = cfg_.pifr_enabled ? cfg_.pifr_text_dim : 0;
  conv_in_ = Conv2d(w, "conv_in", cfg_.in_channels, ch[0], 3, 1, 1);
  time_linear_1_ = Linear(w, "time_embedding.linear_1", ch[0], ted);
  time_linear_2_ = Linear(w, "time_embedding.linear_2", ted, ted);
  add_linear_1_ = Linear(w, "add_embedding.linear_1", cfg_.projection_class_embeddings_input_dim, ted);
  add_linear_2_ = Linear(w, "add_embedding.linear_2", ted, ted);

  for (int64_t i = 0; i < n; ++i) {
    const WeightView b = w.sub("down_blocks." + std::to_string(i));
    const bool cross = cfg_.down_types[size_t(i)] == DownBlockType::CrossAttn;
    const float eps = cross ? 1e-6f : 1e-5f;  // res-block eps is a property of the block type (unet3d.md §9)
    DownBlock d;
    for (int64_t j = 0; j < cfg_.layers_per_block[size_t(i)]; ++j) {
      const int64_t cin = j == 0 ? (i == 0 ? ch[0] : ch[size_t(i - 1)]) : ch[size_t(i)];
      d.resnets.emplace_back(b.sub("resnets." + std::to_string(j)), cin, ch[size_t(i)], ted, eps);
      if (cross)
        d.attentions.emplace_back(b.sub("attentions." + std::to_string(j)), ch[size_t(i)], cfg_.heads[size_t(i)],
                                  cfg_.transformer_layers[size_t(i)], cfg_.cross_attention_dim[size_t(i)], text_dim);
    }
    d.has_downsampler = i + 1 < n;
    if (d.has_downsampler)
      d.downsampler = Conv2d(b.sub("downsamplers.0"), "conv", ch[size_t(i)], ch[size_t(i)], 3, 2, 1);
    down_.push_back(std::move(d));
  }

  const size_t last = size_t(n - 1);
  const WeightView m = w.sub("mid_block");
  mid_res0_ = SpatioTemporalResBlock(m.sub("resnets.0"), ch[last], ch[last], ted, 1e-5f);
  mid_attn_ = TransformerSpatioTemporal(m.sub("attentions.0"), ch[last], cfg_.heads[last],
                                        cfg_.transformer_layers[last], cfg_.cross_attention_dim[last], text_dim);
  mid_res1_ = SpatioTemporalResBlock(m.sub("resnets.1"), ch[last], ch[last], ted, 1e-5f);

  // Up block i uses the reversed per-block lists; resnet j's input is [hidden, skip] (diffusers' channel rule).
  for (int64_t i = 0; i < n; ++i) {
    const size_t r = size_t(n - 1 - i);  // index into the forward lists
    const WeightView b = w.sub("up_blocks." + std::to_string(i));
    const bool cross = cfg_.up_types[size_t(i)] == UpBlockType::CrossAttn;
    const int64_t out = ch[r];
    const int64_t prev_out = i == 0 ? ch[last] : ch[r + 1];
    const int64_t input = ch[r == 0 ? 0 : r - 1];
    const int64_t layers = cfg_.layers_per_block[r] + 1;
    UpBlock u;
    for (int64_t j = 0; j < layers; ++j) {
      const int64_t skip = j == layers - 1 ? input : out;
      const int64_t hidden = j == 0 ? prev_out : out;
      u.resnets.emplace_back(b.sub("resnets." + std::to_string(j)), hidden + skip, out, ted, 1e-6f);
      if (cross)
        u.attentions.emplace_back(b.sub("attentions." + std::to_string(j)), out, cfg_.heads[r],
                                  cfg_.transformer_layers[r], cfg_.cross_attention_dim[r], text_dim);
    }
    u.has_upsampler = i + 1 < n;
    if (u.has_upsampler) u.upsampler = Conv2d(b.sub("upsamplers.0"), "conv", out, out, 3, 1, 1);
    up_.push_back(std::move(u));
  }
  norm_out_ = GroupNorm(w, "conv_norm_out", ch[0], 32, 1e-5f);
  conv_out_ = Conv2d(w, "conv_out", ch[0], cfg_.out_channels, 3, 1, 1);
}

UNetConditioning UNetSpatioTemporal::prepare(const Tensor& ehs, const Tensor* text) const {
  const int64_t B = ehs.dim(0);
  if (ehs.ndim() != 3 || ehs.dim(2) != cfg_.cross_attention_dim[0])
    throw Error("unet: encoder_hidden_states must be [B, tokens, " + std::to_string(cfg_.cross_attention_dim[0]) +
                "], got " + ehs.shape().str());
  if (text) {
    if (!cfg_.pifr_enabled) throw Error("unet: text tokens given but this U-Net has no PIFR layers");
    if (text->ndim() != 3 || text->dim(0) != B || text->dim(2) != cfg_.pifr_text_dim)
      throw Error("unet: text_tokens must be [" + std::to_string(B) + ", tokens, " +
                  std::to_string(cfg_.pifr_text_dim) + "], got " + text->shape().str());
  }
  UNetConditioning c;
  c.videos = B;
  for (const auto& d : down_)
    for (const auto& a : d.attentions) c.transformers.push_back(a.prepare(ehs, text));
  c.transformers.push_back(mid_attn_.prepare(ehs, text));
  for (const auto& u : up_)
    for (const auto& a : u.attentions) c.transformers.push_back(a.prepare(ehs, text));
  return c;
}

Tensor UNetSpatioTemporal::forward(const Tensor& sample, float timestep, const Tensor& ids,
                                   const UNetConditioning& cond) {
  if (sample.ndim() != 5 || sample.dim(2) != cfg_.in_channels)
    throw Error("unet: sample must be [B, F, " + std::to_string(cfg_.in_channels) + ", h, w], got " +
                sample.shape().str());
  const int64_t B = sample.dim(0), F = sample.dim(1), h = sample.dim(3), w = sample.dim(4), N = B * F;
  if (B != cond.videos) throw Error("unet: sample batch " + std::to_string(B) + " does not match the conditioning");
  if (ids.numel() != B * 3) throw Error("unet: added_time_ids must be [" + std::to_string(B) + ", 3]");
  const int64_t down_factor = int64_t(1) << (cfg_.blocks() - 1);
  if (h % down_factor || w % down_factor)
    throw Error("unet: latent size " + std::to_string(h) + "x" + std::to_string(w) + " must be divisible by " +
                std::to_string(down_factor));
  const int64_t ted = cfg_.time_embed_dim(), c0 = cfg_.block_out_channels[0], ad = cfg_.addition_time_embed_dim;
  arena_.reset();
  arena_.shrink_to_peak();  // after the first call: one chunk of exactly what a forward pass needs
  const auto done = [&](const std::string& prefix) {
    if (release_after_use_) weights_->release(prefix);
  };
  std::optional<ScopedStage> stage;
  stage.emplace(profile_, "embeddings");

  // emb [B, ted] = time_embedding(Sin(t, c0)) + add_embedding(concat_k Sin(ids[b, k], ad)); SiLU, per frame
  Tensor tsin({B, c0}), th({B, ted}), emb({B, ted});
  std::vector<float> tv(size_t(B), timestep);
  timestep_embedding(tv.data(), B, c0, tsin.data());
  time_linear_1_.forward(tsin.data(), B, th.data(), Act::SiLU);
  time_linear_2_.forward(th.data(), B, emb.data());
  Tensor aug({B, 3 * ad});
  for (int64_t b = 0; b < B; ++b)
    for (int64_t k = 0; k < 3; ++k) timestep_embedding(ids.data() + b * 3 + k, 1, ad, aug.data() + (b * 3 + k) * ad);
  add_linear_1_.forward(aug.data(), B, th.data(), Act::SiLU);
  add_linear_2_.forward(th.data(), B, emb.data(), Act::None, /*accumulate=*/true);
  Tensor temb_silu({N, ted});  // [B, ted] -> [B*F, ted] (repeat_interleave over frames), then SiLU
  for (int64_t n = 0; n < N; ++n) std::memcpy(temb_silu.data() + n * ted, emb.data() + (n / F) * ted, size_t(ted) * 4);
  silu_inplace(temb_silu.data(), N * ted);

  // [B, F, Cin, h, w] -> [B*F, Cin, h, w] (a view), conv_in
  stage.emplace(profile_, "conv_in_out");
  Tensor x({N, c0, h, w});
  conv_in_.forward(sample.data(), N, h, w, x.data());
  std::vector<Tensor> skips{x};
  size_t ti = 0;  // transformer index into cond
  for (const auto& d : down_) {
    const std::string block = "down_blocks." + std::to_string(&d - down_.data());
    for (size_t j = 0; j < d.resnets.size(); ++j) {
      stage.emplace(profile_, "resblock");
      x = d.resnets[j].forward(x, B, temb_silu.data(), arena_);
      done(block + ".resnets." + std::to_string(j));
      stage.emplace(profile_, "transformer");
      if (!d.attentions.empty()) {
        x = d.attentions[j].forward(x, B, cond.transformers[ti++], arena_);
        done(block + ".attentions." + std::to_string(j));
      }
      skips.push_back(x);
    }
    if (d.has_downsampler) {
      stage.emplace(profile_, "downsample");
      const auto& g = d.downsampler.geom;
      Tensor y({N, g.cout, g.out_h(x.dim(2)), g.out_w(x.dim(3))});
      d.downsampler.forward(x.data(), N, x.dim(2), x.dim(3), y.data());
      x = y;
      skips.push_back(x);
    }
    done(block);
  }
  stage.emplace(profile_, "resblock");
  x = mid_res0_.forward(x, B, temb_silu.data(), arena_);
  done("mid_block.resnets.0");
  stage.emplace(profile_, "transformer");
  x = mid_attn_.forward(x, B, cond.transformers[ti++], arena_);
  done("mid_block.attentions.0");
  stage.emplace(profile_, "resblock");
  x = mid_res1_.forward(x, B, temb_silu.data(), arena_);
  done("mid_block");

  for (const auto& u : up_) {
    const std::string block = "up_blocks." + std::to_string(&u - up_.data());
    for (size_t j = 0; j < u.resnets.size(); ++j) {
      stage.emplace(profile_, "skip_concat");
      Tensor skip = skips.back();
      skips.pop_back();
      const int64_t H = x.dim(2), W = x.dim(3);
      Tensor cat({N, x.dim(1) + skip.dim(1), H, W});  // [hidden, skip] along channels
      concat_channels(x.data(), x.dim(1), skip.data(), skip.dim(1), N, H * W, cat.data());
      stage.emplace(profile_, "resblock");
      x = u.resnets[j].forward(cat, B, temb_silu.data(), arena_);
      done(block + ".resnets." + std::to_string(j));
      stage.emplace(profile_, "transformer");
      if (!u.attentions.empty()) {
        x = u.attentions[j].forward(x, B, cond.transformers[ti++], arena_);
        done(block + ".attentions." + std::to_string(j));
      }
    }
    if (u.has_upsampler) {
      stage.emplace(profile_, "upsample");
      const int64_t C = x.dim(1), H = x.dim(2), W = x.dim(3);
      Tensor up({N, C, 2 * H, 2 * W});
      upsample_nearest2x(x.data(), N * C, H, W, up.data());
      Tensor y({N, C, 2 * H, 2 * W});
      u.upsampler.forward(up.data(), N, 2 * H, 2 * W, y.data());
      x = y;
    }
    done(block);
  }

  stage.emplace(profile_, "conv_in_out");
  Tensor a({N, c0, h, w});
  norm_out_.forward(x.data(), a.data(), N, 1, h * w, /*silu=*/true);
  Tensor out({B, F, cfg_.out_channels, h, w});
  conv_out_.forward(a.data(), N, h, w, out.data());
  done("");  // embeddings, conv_in, conv_out and anything prepare() touched
  return out;
}

}  // namespace egopd
