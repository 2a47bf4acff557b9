#pragma once
// Key mapping from Stability's single-file SVD checkpoint (generative-models naming) to the diffusers / HF layout
// of a model directory (weights.md §4). Pure string rules plus the structure they need from the target configs
// (which original block index is which diffusers block depends on layers_per_block and the block types).
#include <cstdint>
#include <string>
#include <vector>

#include "unet3d/unet_config.h"

namespace egopd {

enum class KeyTransform {
  Copy,
  Squeeze,    // [C, C, 1, 1] -> [C, C] (1x1 conv as Linear); no-op on data
  Transpose,  // 2-D [a, b] -> [b, a]
  SplitQ,     // rows [0, d) of a fused in_proj [3d, ...]
  SplitK,     // rows [d, 2d)
  SplitV,     // rows [2d, 3d)
};

struct KeyTarget {
  std::string component;  // "unet", "vae", "image_encoder"
  std::string key;
  KeyTransform transform = KeyTransform::Copy;
};

struct KeyMapping {
  enum Kind { Mapped, Dropped, Unknown };
  Kind kind = Unknown;
  std::vector<KeyTarget> targets;  // Mapped: one target, or three for a fused q/k/v projection
};

// What the index rules need to know about the architecture.
struct OriginalLayout {
  UNetConfig unet;
  int64_t vae_levels = 4;
  // conditioner.embedders.3.encoder.* present: the VAE encoder comes from there and first_stage_model.encoder.* is
  // a dropped duplicate; otherwise first_stage_model.encoder.* is used (and quant_conv becomes the identity).
  bool has_conditioning_encoder = true;
};

KeyMapping map_original_key(const std::string& key, const OriginalLayout& layout);

// Source prefixes (weights.md §4 table).
inline constexpr const char* kOrigUNetPrefix = "model.diffusion_model.";
inline constexpr const char* kOrigFirstStagePrefix = "first_stage_model.";
inline constexpr const char* kOrigCondEncoderPrefix = "conditioner.embedders.3.encoder.";
inline constexpr const char* kOrigVisionPrefix = "conditioner.embedders.0.open_clip.model.visual.";

// Shape of the target tensor for a source shape (error naming the key if the transform does not apply).
std::vector<int64_t> transformed_shape(const std::string& source_key, const std::vector<int64_t>& shape,
                                       KeyTransform t);
// Writes the target bytes of a transform from the source bytes (element size esize).
void apply_transform(const uint8_t* src, const std::vector<int64_t>& src_shape, size_t esize, KeyTransform t,
                     uint8_t* dst);

}  // namespace egopd
