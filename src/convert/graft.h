#pragma once
// `egopd-convert graft`: a stock SVD-xt diffusers directory + a CLIP text encoder + a tokenizer -> an
// EgoPressureDiff directory whose untrained additions leave the stock behaviour unchanged (egopressurediff.md §6.4):
//   pifr.mod.1 = 0 (so gamma = beta = 0), pifr.attn_text.to_q / to_out.0 copied from the block's attn2,
//   pifr.attn_text.to_k / to_v Xavier-uniform from a fixed seed, mask encoder with a zero conv_out.
#include <cstdint>
#include <string>

#include "convert/tensor_io.h"

namespace egopd {

struct GraftOptions {
  std::string svd_dir, text_encoder_dir, tokenizer_dir, out_dir;
  uint64_t seed = 20240607;  // Xavier init of to_k/to_v and the mask encoder's hidden convs
  WriteOptions write;
};

void graft_model(const GraftOptions& options);

// The PIFR tensor for `key` (…transformer_blocks.N.pifr.<suffix>) of a grafted U-Net: copied from attn2, zero, or
// Xavier-uniform; written as float32 values into out (shape.numel() of them). `stock` supplies attn2.
void graft_pifr_values(const std::string& key, const Shape& shape, const WeightMap& stock, uint64_t seed, float* out);

}  // namespace egopd
