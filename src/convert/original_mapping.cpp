#include "convert/original_mapping.h"

#include <cstring>

#include "core/error.h"

namespace egopd {
namespace {

bool starts(const std::string& s, const std::string& p) { return s.compare(0, p.size(), p) == 0; }

// Consumes "<digits>." from the front of s.
bool take_index(std::string& s, int64_t* out) {
  size_t i = 0;
  while (i < s.size() && i < 6 && s[i] >= '0' && s[i] <= '9') ++i;
  if (i == 0 || i >= s.size() || s[i] != '.') return false;
  *out = std::stoll(s.substr(0, i));
  s = s.substr(i + 1);
  return true;
}

// Consumes the literal prefix p from the front of s.
bool take(std::string& s, const std::string& p) {
  if (!starts(s, p)) return false;
  s = s.substr(p.size());
  return true;
}

struct Rule {
  const char* from;
  const char* to;
};

// First rule whose `from` prefixes rest, applied; empty if none matches. Rules ending without '.' match exactly.
std::string apply_rules(const std::string& rest, const Rule* rules, size_t n) {
  for (size_t i = 0; i < n; ++i) {
    const std::string from = rules[i].from;
    const bool exact = from.back() != '.';
    if (exact ? rest == from : starts(rest, from)) return rules[i].to + rest.substr(from.size());
  }
  return "";
}

// ------------------------------------------------------------------------------------------------ UNet

// VideoResBlock (original) -> SpatioTemporalResBlock (diffusers).
std::string unet_resblock(const std::string& r) {
  static const Rule rules[] = {
      {"time_stack.in_layers.0.", "temporal_res_block.norm1."},
      {"time_stack.in_layers.2.", "temporal_res_block.conv1."},
      {"time_stack.emb_layers.1.", "temporal_res_block.time_emb_proj."},
      {"time_stack.out_layers.0.", "temporal_res_block.norm2."},
      {"time_stack.out_layers.3.", "temporal_res_block.conv2."},
      {"in_layers.0.", "spatial_res_block.norm1."},
      {"in_layers.2.", "spatial_res_block.conv1."},
      {"emb_layers.1.", "spatial_res_block.time_emb_proj."},
      {"out_layers.0.", "spatial_res_block.norm2."},
      {"out_layers.3.", "spatial_res_block.conv2."},
      {"skip_connection.", "spatial_res_block.conv_shortcut."},
      {"time_mixer.mix_factor", "time_mixer.mix_factor"},
  };
  return apply_rules(r, rules, std::size(rules));
}

// SpatialVideoTransformer (original) -> TransformerSpatioTemporalModel (diffusers): identical names except these.
KeyTarget unet_attention(const std::string& prefix, const std::string& r) {
  static const Rule rules[] = {
      {"time_stack.", "temporal_transformer_blocks."},
      {"time_pos_embed.0.", "time_pos_embed.linear_1."},
      {"time_pos_embed.2.", "time_pos_embed.linear_2."},
  };
  std::string mapped = apply_rules(r, rules, std::size(rules));
  if (mapped.empty()) mapped = r;
  const bool proj = r == "proj_in.weight" || r == "proj_out.weight";
  return {"unet", prefix + mapped, proj ? KeyTransform::Squeeze : KeyTransform::Copy};
}

struct InputSlot {
  bool downsample = false;
  int64_t level = 0, j = 0;
};
struct OutputSlot {
  int64_t level = 0, j = 0;
  bool last = false;
};

// input_blocks 1.. in order: per level, layers_per_block res(+attention) blocks, then a downsampler except at the
// last level. output_blocks 0.. : per up level, layers+1 blocks, the last one carrying the upsampler.
std::vector<InputSlot> input_slots(const UNetConfig& c) {
  std::vector<InputSlot> s(1);  // index 0 = conv_in
  for (int64_t L = 0; L < c.blocks(); ++L) {
    for (int64_t j = 0; j < c.layers_per_block[size_t(L)]; ++j) s.push_back({false, L, j});
    if (L + 1 < c.blocks()) s.push_back({true, L, 0});
  }
  return s;
}
std::vector<OutputSlot> output_slots(const UNetConfig& c) {
  std::vector<OutputSlot> s;
  for (int64_t L = 0; L < c.blocks(); ++L) {
    const int64_t n = c.layers_per_block[size_t(c.blocks() - 1 - L)] + 1;
    for (int64_t j = 0; j < n; ++j) s.push_back({L, j, j + 1 == n});
  }
  return s;
}

KeyMapping mapped(KeyTarget t) { return {KeyMapping::Mapped, {std::move(t)}}; }
KeyMapping unknown() { return {KeyMapping::Unknown, {}}; }
KeyMapping dropped() { return {KeyMapping::Dropped, {}}; }

KeyMapping map_unet(std::string r, const UNetConfig& c) {
  static const Rule top[] = {
      {"time_embed.0.", "time_embedding.linear_1."}, {"time_embed.2.", "time_embedding.linear_2."},
      {"label_emb.0.0.", "add_embedding.linear_1."}, {"label_emb.0.2.", "add_embedding.linear_2."},
      {"input_blocks.0.0.", "conv_in."},             {"out.0.", "conv_norm_out."},
      {"out.2.", "conv_out."},
  };
  const std::string t = apply_rules(r, top, std::size(top));
  if (!t.empty()) return mapped({"unet", t});
  int64_t i = 0, s = 0;
  auto res = [&](const std::string& prefix, const std::string& rest) {
    const std::string m = unet_resblock(rest);
    return m.empty() ? unknown() : mapped({"unet", prefix + m});
  };
  if (take(r, "input_blocks.")) {
    const auto slots = input_slots(c);
    if (!take_index(r, &i) || !take_index(r, &s) || i < 1 || i >= int64_t(slots.size())) return unknown();
    const InputSlot& slot = slots[size_t(i)];
    const std::string L = std::to_string(slot.level), j = std::to_string(slot.j);
    if (slot.downsample)
      return s == 0 && take(r, "op.") ? mapped({"unet", "down_blocks." + L + ".downsamplers.0.conv." + r}) : unknown();
    if (s == 0) return res("down_blocks." + L + ".resnets." + j + ".", r);
    if (s == 1 && c.down_types[size_t(slot.level)] == DownBlockType::CrossAttn)
      return mapped(unet_attention("down_blocks." + L + ".attentions." + j + ".", r));
    return unknown();
  }
  if (take(r, "middle_block.")) {
    if (!take_index(r, &s)) return unknown();
    if (s == 0) return res("mid_block.resnets.0.", r);
    if (s == 1) return mapped(unet_attention("mid_block.attentions.0.", r));
    if (s == 2) return res("mid_block.resnets.1.", r);
    return unknown();
  }
  if (take(r, "output_blocks.")) {
    const auto slots = output_slots(c);
    if (!take_index(r, &i) || !take_index(r, &s) || i < 0 || i >= int64_t(slots.size())) return unknown();
    const OutputSlot& slot = slots[size_t(i)];
    const std::string L = std::to_string(slot.level), j = std::to_string(slot.j);
    const bool attn = c.up_types[size_t(slot.level)] == UpBlockType::CrossAttn;
    // The upsampler follows the res-block and, where present, the attention.
    const int64_t up_sub = attn ? 2 : 1;
    if (s == 0) return res("up_blocks." + L + ".resnets." + j + ".", r);
    if (s == 1 && attn) return mapped(unet_attention("up_blocks." + L + ".attentions." + j + ".", r));
    if (s == up_sub && slot.last && slot.level + 1 < c.blocks() && take(r, "conv."))
      return mapped({"unet", "up_blocks." + L + ".upsamplers.0.conv." + r});
    return unknown();
  }
  return unknown();
}

// ------------------------------------------------------------------------------------------------ VAE

KeyMapping vae_mid_attention(const std::string& prefix, const std::string& r) {
  static const Rule rules[] = {
      {"norm.", "group_norm."}, {"q.", "to_q."}, {"k.", "to_k."}, {"v.", "to_v."}, {"proj_out.", "to_out.0."},
  };
  const std::string m = apply_rules(r, rules, std::size(rules));
  if (m.empty()) return unknown();
  const bool squeeze = !starts(r, "norm.") && r.size() > 7 && r.compare(r.size() - 7, 7, ".weight") == 0;
  return mapped({"vae", prefix + m, squeeze ? KeyTransform::Squeeze : KeyTransform::Copy});
}

// Encoder side: keys "encoder.*" / "quant_conv.*" of an AutoencoderKL (prefix already stripped).
KeyMapping map_vae_encoder(std::string r) {
  static const Rule plain[] = {
      {"quant_conv.", "quant_conv."},
      {"encoder.conv_in.", "encoder.conv_in."},
      {"encoder.conv_out.", "encoder.conv_out."},
      {"encoder.norm_out.", "encoder.conv_norm_out."},
      {"encoder.mid.block_1.nin_shortcut.", "encoder.mid_block.resnets.0.conv_shortcut."},
      {"encoder.mid.block_2.nin_shortcut.", "encoder.mid_block.resnets.1.conv_shortcut."},
      {"encoder.mid.block_1.", "encoder.mid_block.resnets.0."},
      {"encoder.mid.block_2.", "encoder.mid_block.resnets.1."},
  };
  const std::string t = apply_rules(r, plain, std::size(plain));
  if (!t.empty()) return mapped({"vae", t});
  if (take(r, "encoder.mid.attn_1.")) return vae_mid_attention("encoder.mid_block.attentions.0.", r);
  int64_t i = 0, j = 0;
  if (take(r, "encoder.down.") && take_index(r, &i)) {
    const std::string pre = "encoder.down_blocks." + std::to_string(i) + ".";
    if (take(r, "downsample.conv.")) return mapped({"vae", pre + "downsamplers.0.conv." + r});
    if (take(r, "block.") && take_index(r, &j)) {
      if (take(r, "nin_shortcut.")) r = "conv_shortcut." + r;
      return mapped({"vae", pre + "resnets." + std::to_string(j) + "." + r});
    }
  }
  return unknown();
}

// VideoResBlock of the temporal decoder -> SpatioTemporalResBlock.
std::string vae_video_resblock(const std::string& r) {
  static const Rule rules[] = {
      {"time_stack.in_layers.0.", "temporal_res_block.norm1."},
      {"time_stack.in_layers.2.", "temporal_res_block.conv1."},
      {"time_stack.out_layers.0.", "temporal_res_block.norm2."},
      {"time_stack.out_layers.3.", "temporal_res_block.conv2."},
      {"nin_shortcut.", "spatial_res_block.conv_shortcut."},
      {"norm1.", "spatial_res_block.norm1."},
      {"conv1.", "spatial_res_block.conv1."},
      {"norm2.", "spatial_res_block.norm2."},
      {"conv2.", "spatial_res_block.conv2."},
      {"mix_factor", "time_mixer.mix_factor"},
  };
  return apply_rules(r, rules, std::size(rules));
}

// Decoder side: keys "decoder.*" (prefix first_stage_model. stripped). Original up.b is indexed by resolution
// level; diffusers' up_blocks are in execution order.
KeyMapping map_vae_decoder(std::string r, int64_t levels) {
  static const Rule plain[] = {
      {"decoder.conv_in.", "decoder.conv_in."},
      {"decoder.norm_out.", "decoder.conv_norm_out."},
      {"decoder.conv_out.time_mix_conv.", "decoder.time_conv_out."},
      {"decoder.conv_out.", "decoder.conv_out."},
  };
  const std::string t = apply_rules(r, plain, std::size(plain));
  if (!t.empty()) return mapped({"vae", t});
  auto res = [](const std::string& prefix, const std::string& rest) {
    const std::string m = vae_video_resblock(rest);
    return m.empty() ? unknown() : mapped({"vae", prefix + m});
  };
  if (take(r, "decoder.mid.block_1.")) return res("decoder.mid_block.resnets.0.", r);
  if (take(r, "decoder.mid.block_2.")) return res("decoder.mid_block.resnets.1.", r);
  if (take(r, "decoder.mid.attn_1.")) return vae_mid_attention("decoder.mid_block.attentions.0.", r);
  int64_t b = 0, j = 0;
  if (take(r, "decoder.up.") && take_index(r, &b) && b >= 0 && b < levels) {
    const std::string pre = "decoder.up_blocks." + std::to_string(levels - 1 - b) + ".";
    if (take(r, "upsample.conv.")) return mapped({"vae", pre + "upsamplers.0.conv." + r});
    if (take(r, "block.") && take_index(r, &j)) return res(pre + "resnets." + std::to_string(j) + ".", r);
  }
  return unknown();
}

// ------------------------------------------------------------------------------------------------ CLIP vision

KeyMapping map_vision(std::string r) {
  static const Rule plain[] = {
      {"conv1.weight", "vision_model.embeddings.patch_embedding.weight"},
      {"class_embedding", "vision_model.embeddings.class_embedding"},
      {"positional_embedding", "vision_model.embeddings.position_embedding.weight"},
      {"ln_pre.", "vision_model.pre_layrnorm."},
      {"ln_post.", "vision_model.post_layernorm."},
  };
  const std::string t = apply_rules(r, plain, std::size(plain));
  if (!t.empty()) return mapped({"image_encoder", t});
  if (r == "proj") return mapped({"image_encoder", "visual_projection.weight", KeyTransform::Transpose});
  int64_t n = 0;
  if (!take(r, "transformer.resblocks.") || !take_index(r, &n)) return unknown();
  const std::string pre = "vision_model.encoder.layers." + std::to_string(n) + ".";
  if (r == "attn.in_proj_weight" || r == "attn.in_proj_bias") {
    const std::string suffix = r == "attn.in_proj_weight" ? "weight" : "bias";
    return {KeyMapping::Mapped,
            {{"image_encoder", pre + "self_attn.q_proj." + suffix, KeyTransform::SplitQ},
             {"image_encoder", pre + "self_attn.k_proj." + suffix, KeyTransform::SplitK},
             {"image_encoder", pre + "self_attn.v_proj." + suffix, KeyTransform::SplitV}}};
  }
  static const Rule layer[] = {
      {"ln_1.", "layer_norm1."},           {"ln_2.", "layer_norm2."}, {"attn.out_proj.", "self_attn.out_proj."},
      {"mlp.c_fc.", "mlp.fc1."},           {"mlp.c_proj.", "mlp.fc2."},
  };
  const std::string m = apply_rules(r, layer, std::size(layer));
  return m.empty() ? unknown() : mapped({"image_encoder", pre + m});
}

// Leftovers of the deleted OpenCLIP text tower next to `visual.` (weights.md §4).
bool is_dropped_text_leftover(const std::string& r) {
  return r == "positional_embedding" || r == "text_projection" || r == "logit_scale" || r == "attn_mask" ||
         starts(r, "token_embedding.") || starts(r, "ln_final.") || starts(r, "transformer.");
}

}  // namespace

KeyMapping map_original_key(const std::string& key, const OriginalLayout& layout) {
  std::string r = key;
  if (take(r, kOrigUNetPrefix)) return map_unet(r, layout.unet);
  if (take(r, kOrigCondEncoderPrefix)) {
    // The conditioning engine (AutoencoderKLModeOnly) may also carry a decoder side that SVD never runs.
    if (starts(r, "decoder.") || starts(r, "post_quant_conv.")) return dropped();
    return map_vae_encoder(r);
  }
  if (take(r, kOrigFirstStagePrefix)) {
    if (starts(r, "decoder.")) return map_vae_decoder(r, layout.vae_levels);
    if (starts(r, "encoder.")) return layout.has_conditioning_encoder ? dropped() : map_vae_encoder(r);
    return unknown();
  }
  if (take(r, kOrigVisionPrefix)) return map_vision(r);
  if (take(r, "conditioner.embedders.0.open_clip.model.")) return is_dropped_text_leftover(r) ? dropped() : unknown();
  for (const char* p : {"model_ema.", "conditioner.embedders.1.", "conditioner.embedders.2.", "conditioner.embedders.4."})
    if (starts(key, p)) return dropped();
  return unknown();
}

std::vector<int64_t> transformed_shape(const std::string& key, const std::vector<int64_t>& s, KeyTransform t) {
  switch (t) {
    case KeyTransform::Copy:
      return s;
    case KeyTransform::Squeeze:
      if (s.size() == 4 && s[2] == 1 && s[3] == 1) return {s[0], s[1]};
      if (s.size() == 2) return s;
      throw Error(key + ": expected a [C,C,1,1] or [C,C] weight, got " + std::to_string(s.size()) + "-D");
    case KeyTransform::Transpose:
      if (s.size() != 2) throw Error(key + ": expected a 2-D matrix to transpose");
      return {s[1], s[0]};
    case KeyTransform::SplitQ:
    case KeyTransform::SplitK:
    case KeyTransform::SplitV: {
      if (s.empty() || s[0] % 3 != 0) throw Error(key + ": fused q/k/v projection's first dimension is not 3 x width");
      std::vector<int64_t> out = s;
      out[0] /= 3;
      return out;
    }
  }
  return s;
}

void apply_transform(const uint8_t* src, const std::vector<int64_t>& s, size_t esize, KeyTransform t, uint8_t* dst) {
  size_t n = esize;
  for (int64_t d : s) n *= size_t(d);
  switch (t) {
    case KeyTransform::Copy:
    case KeyTransform::Squeeze:
      std::memcpy(dst, src, n);
      return;
    case KeyTransform::Transpose: {
      const size_t rows = size_t(s[0]), cols = size_t(s[1]);
      for (size_t i = 0; i < rows; ++i)
        for (size_t j = 0; j < cols; ++j) std::memcpy(dst + (j * rows + i) * esize, src + (i * cols + j) * esize, esize);
      return;
    }
    case KeyTransform::SplitQ:
    case KeyTransform::SplitK:
    case KeyTransform::SplitV: {
      const size_t part = n / 3;
      const size_t which = t == KeyTransform::SplitQ ? 0 : t == KeyTransform::SplitK ? 1 : 2;
      std::memcpy(dst, src + which * part, part);
      return;
    }
  }
}

}  // namespace egopd
