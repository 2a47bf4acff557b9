#include "unet3d/unet_config.h"

#include <filesystem>

#include "core/error.h"

namespace egopd {

UNetConfig UNetConfig::from(const Config& c) {
  UNetConfig u;
  u.in_channels = c.get_int("in_channels", 8, kChannelRange);
  u.out_channels = c.get_int("out_channels", 4, kChannelRange);
  u.block_out_channels = c.get_int_list("block_out_channels", kChannelRange);
  const size_t n = u.block_out_channels.size();
  if (n == 0) c.fail("block_out_channels", "empty");
  for (const auto& t : c.get_string_list("down_block_types")) {
    if (t == "CrossAttnDownBlockSpatioTemporal") u.down_types.push_back(DownBlockType::CrossAttn);
    else if (t == "DownBlockSpatioTemporal") u.down_types.push_back(DownBlockType::Plain);
    else c.fail("down_block_types", "unsupported block type " + t);
  }
  for (const auto& t : c.get_string_list("up_block_types")) {
    if (t == "CrossAttnUpBlockSpatioTemporal") u.up_types.push_back(UpBlockType::CrossAttn);
    else if (t == "UpBlockSpatioTemporal") u.up_types.push_back(UpBlockType::Plain);
    else c.fail("up_block_types", "unsupported block type " + t);
  }
  if (u.down_types.size() != n) c.fail("down_block_types", "needs one entry per block_out_channels entry");
  if (u.up_types.size() != n) c.fail("up_block_types", "needs one entry per block_out_channels entry");
  u.layers_per_block = c.get_int_per_block("layers_per_block", n, kCountRange);
  u.transformer_layers = c.get_int_per_block("transformer_layers_per_block", n, kCountRange);
  u.heads = c.get_int_per_block("num_attention_heads", n, kCountRange);
  u.cross_attention_dim = c.get_int_per_block("cross_attention_dim", n, kChannelRange);
  u.addition_time_embed_dim = c.get_int("addition_time_embed_dim", 256, kChannelRange);
  u.projection_class_embeddings_input_dim = c.get_int("projection_class_embeddings_input_dim", 768, kChannelRange);
  if (u.projection_class_embeddings_input_dim != 3 * u.addition_time_embed_dim)
    c.fail("projection_class_embeddings_input_dim", "must be 3 x addition_time_embed_dim (three added time ids)");
  for (size_t i = 0; i < n; ++i) {
    if (u.block_out_channels[i] <= 0 || u.block_out_channels[i] % 32)
      c.fail("block_out_channels", "each width must be a positive multiple of 32 (GroupNorm groups)");
    if (u.heads[i] <= 0 || u.block_out_channels[i] % u.heads[i])
      c.fail("num_attention_heads", "must divide the block width");
    if (u.layers_per_block[i] < 1) c.fail("layers_per_block", "must be at least 1");
    if (u.transformer_layers[i] < 1) c.fail("transformer_layers_per_block", "must be at least 1");
  }
  if (c.has("pifr")) {
    Config p = c.sub("pifr");
    u.pifr_enabled = p.get_bool("enabled", true);
    if (u.pifr_enabled) u.pifr_text_dim = p.get_int("text_dim", kChannelRange);
  }
  return u;
}

UNetConfig UNetConfig::load(const std::string& unet_dir) {
  return from(Config::load((std::filesystem::path(unet_dir) / "config.json").string()));
}

UNetConfig UNetConfig::svd_xt(bool pifr) {
  UNetConfig u;
  u.down_types = {DownBlockType::CrossAttn, DownBlockType::CrossAttn, DownBlockType::CrossAttn, DownBlockType::Plain};
  u.up_types = {UpBlockType::Plain, UpBlockType::CrossAttn, UpBlockType::CrossAttn, UpBlockType::CrossAttn};
  u.block_out_channels = {320, 640, 1280, 1280};
  u.layers_per_block = {2, 2, 2, 2};
  u.transformer_layers = {1, 1, 1, 1};
  u.heads = {5, 10, 20, 20};
  u.cross_attention_dim = {1024, 1024, 1024, 1024};
  u.pifr_enabled = pifr;
  u.pifr_text_dim = pifr ? 1024 : 0;
  return u;
}

}  // namespace egopd
