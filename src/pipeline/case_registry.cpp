#include "pipeline/case_registry.h"

namespace egopd {

// Runners live beside their components (src/<component>/*_case.cpp).
// Add one declaration and one table row per component.
// -- declarations --
CaseOutputs run_unet_case(const GoldenCase&);
CaseOutputs run_clip_vision_case(const GoldenCase&);
CaseOutputs run_image_preprocess_case(const GoldenCase&);
CaseOutputs run_clip_text_case(const GoldenCase&);
CaseOutputs run_tokenizer_case(const GoldenCase&);
CaseOutputs run_vae_encode_case(const GoldenCase&);
CaseOutputs run_vae_decode_case(const GoldenCase&);
CaseOutputs run_rng_case(const GoldenCase&);
CaseOutputs run_scheduler_euler_case(const GoldenCase&);
CaseOutputs run_scheduler_lcm_case(const GoldenCase&);
CaseOutputs run_mask_encoder_case(const GoldenCase&);
CaseOutputs run_svd_pipeline_case(const GoldenCase&);
// -- end declarations --

namespace {
struct Entry {
  const char* component;
  CaseRunner run;
};
const Entry kRunners[] = {
    // -- table --
    {"", nullptr},
    {"unet", run_unet_case},
    {"unet_pifr", run_unet_case},
    {"clip_vision", run_clip_vision_case},
    {"image_preprocess", run_image_preprocess_case},
    {"clip_text", run_clip_text_case},
    {"tokenizer", run_tokenizer_case},
    {"vae_encode", run_vae_encode_case},
    {"vae_decode", run_vae_decode_case},
    {"rng", run_rng_case},
    {"scheduler_euler", run_scheduler_euler_case},
    {"scheduler_lcm", run_scheduler_lcm_case},
    {"mask_encoder", run_mask_encoder_case},
    {"svd_pipeline", run_svd_pipeline_case},
    // -- end table --
};
}  // namespace

CaseRunner find_case_runner(const std::string& component) {
  for (const auto& e : kRunners)
    if (e.run && component == e.component) return e.run;
  return nullptr;
}

std::vector<std::string> case_components() {
  std::vector<std::string> v;
  for (const auto& e : kRunners)
    if (e.run) v.push_back(e.component);
  return v;
}

}  // namespace egopd
