#include "mask_encoder/mask_encoder.h"

#include <filesystem>

#include "core/error.h"

namespace egopd {

MaskEncoderConfig MaskEncoderConfig::from(const Config& c) {
  const std::string cls = c.get_string("_class_name", "MaskEncoder");
  if (cls != "MaskEncoder" && cls != "ControlNetConditioningEmbedding")
    c.fail("_class_name", "expected MaskEncoder or ControlNetConditioningEmbedding, got " + cls);
  MaskEncoderConfig m;
  m.conditioning_channels = c.get_int("conditioning_channels", 1, kChannelRange);
  if (c.has("block_out_channels")) m.block_out_channels = c.get_int_list("block_out_channels", kChannelRange);
  m.conditioning_embedding_channels = c.get_int("conditioning_embedding_channels", 8, kChannelRange);
  if (m.block_out_channels.empty()) c.fail("block_out_channels", "must not be empty");
  return m;
}

MaskEncoderConfig MaskEncoderConfig::load(const std::string& dir) {
  return from(Config::load((std::filesystem::path(dir) / "config.json").string()));
}

MaskEncoder::MaskEncoder(const std::string& dir)
    : MaskEncoder(MaskEncoderConfig::load(dir),
                  std::make_shared<WeightMap>(WeightMap::load_dir(dir, "diffusion_pytorch_model", "mask_encoder"))) {}

MaskEncoder::MaskEncoder(const MaskEncoderConfig& cfg, std::shared_ptr<const WeightMap> weights)
    : cfg_(cfg), weights_(std::move(weights)) {
  const WeightView w = weights_->root();
  const auto& c = cfg_.block_out_channels;
  conv_in_ = Conv2d(w, "conv_in", cfg_.conditioning_channels, c[0], 3, 1, 1);
  for (size_t i = 0; i + 1 < c.size(); ++i) {
    blocks_.emplace_back(w, "blocks." + std::to_string(2 * i), c[i], c[i], 3, 1, 1);
    blocks_.emplace_back(w, "blocks." + std::to_string(2 * i + 1), c[i], c[i + 1], 3, 2, 1);
  }
  conv_out_ = Conv2d(w, "conv_out", c.back(), cfg_.conditioning_embedding_channels, 3, 1, 1);
  weights_->check_all_used({});
}

Tensor MaskEncoder::forward(const Tensor& m) const {
  if (m.ndim() != 4 || m.dim(1) != cfg_.conditioning_channels)
    throw Error("mask_encoder: masks must be [F, " + std::to_string(cfg_.conditioning_channels) + ", S, S], got " +
                m.shape().str());
  const int64_t F = m.dim(0);
  int64_t H = m.dim(2), W = m.dim(3);
  if (H % cfg_.downscale() || W % cfg_.downscale())
    throw Error("mask_encoder: mask size " + std::to_string(H) + "x" + std::to_string(W) + " must be divisible by " +
                std::to_string(cfg_.downscale()));
  Tensor e({F, conv_in_.geom.cout, H, W});
  conv_in_.forward(m.data(), F, H, W, e.data(), Act::SiLU);
  for (const Conv2d& b : blocks_) {
    const int64_t Ho = b.geom.out_h(H), Wo = b.geom.out_w(W);
    Tensor y({F, b.geom.cout, Ho, Wo});
    b.forward(e.data(), F, H, W, y.data(), Act::SiLU);
    e = y, H = Ho, W = Wo;
  }
  Tensor out({F, conv_out_.geom.cout, H, W});
  conv_out_.forward(e.data(), F, H, W, out.data());
  return out;
}

}  // namespace egopd
