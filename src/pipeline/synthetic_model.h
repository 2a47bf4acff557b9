#pragma once
// Model-directory building blocks shared by `egopd` (its built-in default model) and `egopd-convert`:
// the component table of weights.md §1, the configs of the two presets ("tiny", "svd-xt"), the exact parameter
// list of a component (recorded from the model class built from its config), and write_synthetic_model(), which
// writes a complete EgoPressureDiff model directory with deterministic random weights.
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/config.h"
#include "core/dtype.h"
#include "core/tensor.h"

namespace egopd {

// A weight-carrying component folder of a model directory and the stem of its weight file.
struct ModelComponent {
  const char* folder;  // "unet", "vae", "image_encoder", "text_encoder", "mask_encoder"
  const char* stem;    // "diffusion_pytorch_model" (diffusers) or "model" (transformers)
  const char* library;
  const char* class_name;
};
const std::vector<ModelComponent>& model_components();
const ModelComponent& model_component(const std::string& folder);  // error for an unknown folder

// Config JSON of one component for a preset: preset "tiny" | "svd-xt"; folder as in model_components().
nlohmann::json preset_config(const std::string& preset, const std::string& folder);
// scheduler/scheduler_config.json: Euler (SVD-xt, scheduler.md §1.1) for lcm_steps 0, else AnimateLCM (§3.1).
nlohmann::json scheduler_config_json(int lcm_steps);
// feature_extractor/preprocessor_config.json (CLIP mean/std, size 224).
nlohmann::json preprocessor_config_json();
// model_index.json of an EgoPressureDiff directory (weights.md §1.1); egopd_defaults.num_inference_steps is 25 for
// the Euler teacher, lcm_steps for a student. Components absent from the directory are left out.
nlohmann::json model_index_json(int lcm_steps, bool has_text, bool has_mask_encoder);

// Every (key, shape) the runtime's model class for `folder` requests when built from `config` (duplicates
// removed, construction order). PIFR keys are included when the U-Net config enables PIFR.
std::vector<std::pair<std::string, Shape>> component_parameters(const std::string& folder, const Config& config);

// Folder holding the CLIP BPE files (vocab.json, merges.txt, tokenizer_config.json) shipped with egopd:
// EGOPD_TOKENIZER_DIR if set, else <prefix>/share/egopd/tokenizer next to the executable, else the source tree.
std::string shipped_tokenizer_dir();

// Writes a complete model directory (weights.md §1) with deterministic random weights from `seed`: preset "tiny"
// (small, fast, dims consistent) or "svd-xt" (real sizes); dtype F32/F16/BF16; lcm_steps 0 (Euler, 25 steps) or
// the step count of an AnimateLCM student (1..40). Every file is written atomically.
void write_synthetic_model(const std::string& dir, const std::string& preset, uint64_t seed, DType dtype,
                           int lcm_steps);

// Sixteen hex digits that identify what write_synthetic_model writes for these arguments (every component's config,
// parameter names and shapes, seed and dtype, the generator's values, the scheduler, preprocessor and index files;
// not the shipped tokenizer files): a cache folder named by it is never reused by a build that would write another
// model.
std::string synthetic_model_id(const std::string& preset, uint64_t seed, DType dtype, int lcm_steps);

// Writes JSON (indented, trailing newline) atomically.
void write_json_atomic(const std::string& path, const nlohmann::json& j);

}  // namespace egopd
