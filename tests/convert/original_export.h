#pragma once
// Test-side inverse of weights.md §4: diffusers / HF key -> Stability's single-file key, written independently of
// src/convert/original_mapping.cpp (rules read off the spec tables, index arithmetic from the block structure), so a
// round trip through both checks each against the other.
#include <cstdint>
#include <regex>
#include <string>
#include <vector>

namespace egopd::test {

struct OriginalPiece {
  std::string key;
  std::vector<int64_t> shape;  // shape of the whole original tensor
  enum How { Whole, RowBlock, Transposed } how = Whole;
  int part = 0;  // RowBlock: which third (q, k, v)
};

struct ExportLayout {
  int64_t unet_layers = 2;  // layers_per_block (same at every level)
  std::vector<bool> up_attention{false, true, true, true};
  int64_t vae_levels = 4;
};

namespace detail {

inline bool sub(std::string& s, const std::string& pattern, const std::string& repl) {
  const std::regex re(pattern);
  if (!std::regex_search(s, re)) return false;
  s = std::regex_replace(s, re, repl, std::regex_constants::format_first_only);
  return true;
}

inline std::string unet_res(std::string r) {
  static const std::pair<const char*, const char*> rules[] = {
      {"^spatial_res_block\\.norm1\\.", "in_layers.0."},
      {"^spatial_res_block\\.conv1\\.", "in_layers.2."},
      {"^spatial_res_block\\.time_emb_proj\\.", "emb_layers.1."},
      {"^spatial_res_block\\.norm2\\.", "out_layers.0."},
      {"^spatial_res_block\\.conv2\\.", "out_layers.3."},
      {"^spatial_res_block\\.conv_shortcut\\.", "skip_connection."},
      {"^temporal_res_block\\.norm1\\.", "time_stack.in_layers.0."},
      {"^temporal_res_block\\.conv1\\.", "time_stack.in_layers.2."},
      {"^temporal_res_block\\.time_emb_proj\\.", "time_stack.emb_layers.1."},
      {"^temporal_res_block\\.norm2\\.", "time_stack.out_layers.0."},
      {"^temporal_res_block\\.conv2\\.", "time_stack.out_layers.3."},
  };
  for (const auto& [p, q] : rules)
    if (sub(r, p, q)) return r;
  return r;  // time_mixer.mix_factor
}

inline std::string unet_attn(std::string r) {
  sub(r, "^temporal_transformer_blocks\\.", "time_stack.") || sub(r, "^time_pos_embed\\.linear_1\\.", "time_pos_embed.0.") ||
      sub(r, "^time_pos_embed\\.linear_2\\.", "time_pos_embed.2.");
  return r;
}

inline std::string vae_res(std::string r) {
  sub(r, "^conv_shortcut\\.", "nin_shortcut.");
  return r;
}

inline std::string vae_video_res(std::string r) {
  sub(r, "^spatial_res_block\\.conv_shortcut\\.", "nin_shortcut.") || sub(r, "^spatial_res_block\\.", "") ||
      sub(r, "^temporal_res_block\\.norm1\\.", "time_stack.in_layers.0.") ||
      sub(r, "^temporal_res_block\\.conv1\\.", "time_stack.in_layers.2.") ||
      sub(r, "^temporal_res_block\\.norm2\\.", "time_stack.out_layers.0.") ||
      sub(r, "^temporal_res_block\\.conv2\\.", "time_stack.out_layers.3.") || sub(r, "^time_mixer\\.mix_factor$", "mix_factor");
  return r;
}

inline std::string vae_attn(std::string r) {
  sub(r, "^group_norm\\.", "norm.") || sub(r, "^to_q\\.", "q.") || sub(r, "^to_k\\.", "k.") || sub(r, "^to_v\\.", "v.") ||
      sub(r, "^to_out\\.0\\.", "proj_out.");
  return r;
}

}  // namespace detail

inline OriginalPiece unet_to_original(const std::string& key, const std::vector<int64_t>& shape, const ExportLayout& l) {
  using detail::sub;
  const std::string P = "model.diffusion_model.";
  std::smatch m;
  std::string k = key;
  if (sub(k, "^conv_in\\.", "input_blocks.0.0.") || sub(k, "^time_embedding\\.linear_1\\.", "time_embed.0.") ||
      sub(k, "^time_embedding\\.linear_2\\.", "time_embed.2.") || sub(k, "^add_embedding\\.linear_1\\.", "label_emb.0.0.") ||
      sub(k, "^add_embedding\\.linear_2\\.", "label_emb.0.2.") || sub(k, "^conv_norm_out\\.", "out.0.") ||
      sub(k, "^conv_out\\.", "out.2."))
    return {P + k, shape};
  const int64_t per_level = l.unet_layers + 1;  // res blocks + downsampler (down) / res blocks (up, lpb + 1)
  if (std::regex_match(key, m, std::regex("down_blocks\\.(\\d+)\\.resnets\\.(\\d+)\\.(.*)")))
    return {P + "input_blocks." + std::to_string(1 + std::stoll(m[1]) * per_level + std::stoll(m[2])) + ".0." +
                detail::unet_res(m[3]),
            shape};
  if (std::regex_match(key, m, std::regex("down_blocks\\.(\\d+)\\.attentions\\.(\\d+)\\.(.*)"))) {
    const bool proj_in = m[3] == "proj_in.weight";  // exported as a 1x1 conv to exercise the squeeze rule
    return {P + "input_blocks." + std::to_string(1 + std::stoll(m[1]) * per_level + std::stoll(m[2])) + ".1." +
                detail::unet_attn(m[3]),
            proj_in ? std::vector<int64_t>{shape[0], shape[1], 1, 1} : shape};
  }
  if (std::regex_match(key, m, std::regex("down_blocks\\.(\\d+)\\.downsamplers\\.0\\.conv\\.(.*)")))
    return {P + "input_blocks." + std::to_string(1 + std::stoll(m[1]) * per_level + l.unet_layers) + ".0.op." +
                std::string(m[2]),
            shape};
  if (std::regex_match(key, m, std::regex("mid_block\\.resnets\\.(\\d)\\.(.*)")))
    return {P + "middle_block." + (m[1] == "0" ? "0." : "2.") + detail::unet_res(m[2]), shape};
  if (std::regex_match(key, m, std::regex("mid_block\\.attentions\\.0\\.(.*)")))
    return {P + "middle_block.1." + detail::unet_attn(m[1]), shape};
  if (std::regex_match(key, m, std::regex("up_blocks\\.(\\d+)\\.resnets\\.(\\d+)\\.(.*)")))
    return {P + "output_blocks." + std::to_string(std::stoll(m[1]) * per_level + std::stoll(m[2])) + ".0." +
                detail::unet_res(m[3]),
            shape};
  if (std::regex_match(key, m, std::regex("up_blocks\\.(\\d+)\\.attentions\\.(\\d+)\\.(.*)")))
    return {P + "output_blocks." + std::to_string(std::stoll(m[1]) * per_level + std::stoll(m[2])) + ".1." +
                detail::unet_attn(m[3]),
            shape};
  if (std::regex_match(key, m, std::regex("up_blocks\\.(\\d+)\\.upsamplers\\.0\\.conv\\.(.*)"))) {
    const int64_t L = std::stoll(m[1]);
    return {P + "output_blocks." + std::to_string(L * per_level + l.unet_layers) + "." +
                (l.up_attention[size_t(L)] ? "2" : "1") + ".conv." + std::string(m[2]),
            shape};
  }
  return {"unexported." + key, shape};
}

// with_cond_encoder: the encoder side goes to conditioner.embedders.3.encoder.* (else first_stage_model.encoder.*).
inline OriginalPiece vae_to_original(const std::string& key, const std::vector<int64_t>& shape, const ExportLayout& l,
                                     bool with_cond_encoder) {
  std::smatch m;
  const std::string E = with_cond_encoder ? "conditioner.embedders.3.encoder." : "first_stage_model.";
  const auto squeeze_back = [&](const std::string& r) {
    return shape.size() == 2 && r.find("to_") == 0 ? std::vector<int64_t>{shape[0], shape[1], 1, 1} : shape;
  };
  if (key.rfind("quant_conv.", 0) == 0) return {E + key, shape};
  if (std::regex_match(key, m, std::regex("encoder\\.down_blocks\\.(\\d+)\\.resnets\\.(\\d+)\\.(.*)")))
    return {E + "encoder.down." + std::string(m[1]) + ".block." + std::string(m[2]) + "." + detail::vae_res(m[3]), shape};
  if (std::regex_match(key, m, std::regex("encoder\\.down_blocks\\.(\\d+)\\.downsamplers\\.0\\.conv\\.(.*)")))
    return {E + "encoder.down." + std::string(m[1]) + ".downsample.conv." + std::string(m[2]), shape};
  if (std::regex_match(key, m, std::regex("encoder\\.mid_block\\.resnets\\.(\\d)\\.(.*)")))
    return {E + "encoder.mid.block_" + (m[1] == "0" ? "1." : "2.") + detail::vae_res(m[2]), shape};
  if (std::regex_match(key, m, std::regex("encoder\\.mid_block\\.attentions\\.0\\.(.*)")))
    return {E + "encoder.mid.attn_1." + detail::vae_attn(m[1]), squeeze_back(m[1])};
  if (key == "encoder.conv_norm_out.weight" || key == "encoder.conv_norm_out.bias")
    return {E + "encoder.norm_out." + key.substr(key.rfind('.') + 1), shape};
  if (key.rfind("encoder.", 0) == 0) return {E + key, shape};  // conv_in, conv_out

  const std::string D = "first_stage_model.decoder.";
  if (std::regex_match(key, m, std::regex("decoder\\.up_blocks\\.(\\d+)\\.resnets\\.(\\d+)\\.(.*)")))
    return {D + "up." + std::to_string(l.vae_levels - 1 - std::stoll(m[1])) + ".block." + std::string(m[2]) + "." +
                detail::vae_video_res(m[3]),
            shape};
  if (std::regex_match(key, m, std::regex("decoder\\.up_blocks\\.(\\d+)\\.upsamplers\\.0\\.conv\\.(.*)")))
    return {D + "up." + std::to_string(l.vae_levels - 1 - std::stoll(m[1])) + ".upsample.conv." + std::string(m[2]),
            shape};
  if (std::regex_match(key, m, std::regex("decoder\\.mid_block\\.resnets\\.(\\d)\\.(.*)")))
    return {D + "mid.block_" + (m[1] == "0" ? "1." : "2.") + detail::vae_video_res(m[2]), shape};
  if (std::regex_match(key, m, std::regex("decoder\\.mid_block\\.attentions\\.0\\.(.*)")))
    return {D + "mid.attn_1." + detail::vae_attn(m[1]), squeeze_back(m[1])};
  if (std::regex_match(key, m, std::regex("decoder\\.conv_norm_out\\.(.*)"))) return {D + "norm_out." + std::string(m[1]), shape};
  if (std::regex_match(key, m, std::regex("decoder\\.time_conv_out\\.(.*)")))
    return {D + "conv_out.time_mix_conv." + std::string(m[1]), shape};
  if (std::regex_match(key, m, std::regex("decoder\\.(conv_in|conv_out)\\.(.*)"))) return {"first_stage_model." + key, shape};
  return {"unexported." + key, shape};
}

inline OriginalPiece vision_to_original(const std::string& key, const std::vector<int64_t>& shape) {
  const std::string V = "conditioner.embedders.0.open_clip.model.visual.";
  std::smatch m;
  if (key == "vision_model.embeddings.patch_embedding.weight") return {V + "conv1.weight", shape};
  if (key == "vision_model.embeddings.class_embedding") return {V + "class_embedding", shape};
  if (key == "vision_model.embeddings.position_embedding.weight") return {V + "positional_embedding", shape};
  if (key == "visual_projection.weight") return {V + "proj", {shape[1], shape[0]}, OriginalPiece::Transposed};
  if (std::regex_match(key, m, std::regex("vision_model\\.(pre_layrnorm|post_layernorm)\\.(.*)")))
    return {V + (m[1] == "pre_layrnorm" ? "ln_pre." : "ln_post.") + std::string(m[2]), shape};
  if (std::regex_match(key, m, std::regex("vision_model\\.encoder\\.layers\\.(\\d+)\\.self_attn\\.([qkv])_proj\\.(weight|bias)"))) {
    std::vector<int64_t> fused = shape;
    fused[0] *= 3;
    const int part = m[2] == "q" ? 0 : m[2] == "k" ? 1 : 2;
    return {V + "transformer.resblocks." + std::string(m[1]) + ".attn.in_proj_" + std::string(m[3]), fused,
            OriginalPiece::RowBlock, part};
  }
  if (std::regex_match(key, m, std::regex("vision_model\\.encoder\\.layers\\.(\\d+)\\.(.*)"))) {
    std::string r = m[2];
    detail::sub(r, "^layer_norm1\\.", "ln_1.") || detail::sub(r, "^layer_norm2\\.", "ln_2.") ||
        detail::sub(r, "^self_attn\\.out_proj\\.", "attn.out_proj.") || detail::sub(r, "^mlp\\.fc1\\.", "mlp.c_fc.") ||
        detail::sub(r, "^mlp\\.fc2\\.", "mlp.c_proj.");
    return {V + "transformer.resblocks." + std::string(m[1]) + "." + r, shape};
  }
  return {"unexported." + key, shape};
}

}  // namespace egopd::test
