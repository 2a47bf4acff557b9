#pragma once
// UNetSpatioTemporalConditionModel configuration (unet/config.json), with per-block values expanded.
#include <string>
#include <vector>

#include "core/config.h"

namespace egopd {

enum class DownBlockType { CrossAttn, Plain };  // CrossAttnDownBlockSpatioTemporal / DownBlockSpatioTemporal
enum class UpBlockType { CrossAttn, Plain };    // CrossAttnUpBlockSpatioTemporal / UpBlockSpatioTemporal

struct UNetConfig {
  int64_t in_channels = 8, out_channels = 4;
  std::vector<DownBlockType> down_types;
  std::vector<UpBlockType> up_types;
  std::vector<int64_t> block_out_channels;
  std::vector<int64_t> layers_per_block;        // per down block
  std::vector<int64_t> transformer_layers;      // per down block
  std::vector<int64_t> heads;                   // per down block
  std::vector<int64_t> cross_attention_dim;     // per down block
  int64_t addition_time_embed_dim = 256;
  int64_t projection_class_embeddings_input_dim = 768;
  bool pifr_enabled = false;
  int64_t pifr_text_dim = 0;

  int64_t blocks() const { return int64_t(block_out_channels.size()); }
  int64_t time_embed_dim() const { return 4 * block_out_channels[0]; }
  static UNetConfig from(const Config& c);
  static UNetConfig load(const std::string& unet_dir);
  // The SVD-xt configuration (unet3d.md §1), optionally with PIFR (text_dim 1024).
  static UNetConfig svd_xt(bool pifr);
};

}  // namespace egopd
