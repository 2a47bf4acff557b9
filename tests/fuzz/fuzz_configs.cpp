// Every config reader on the same JSON document: U-Net, VAE, CLIP text and vision towers, mask encoder, both
// samplers, the model_index defaults, the CLIP image normalisation (feature extractor) and the hand template.
#include "clip_image/clip_encoder.h"
#include "clip_image/clip_vision.h"
#include "clip_image/svd_preprocess.h"
#include "core/config.h"
#include "core/json_text.h"
#include "fuzz_common.h"
#include "mask_encoder/mask_encoder.h"
#include "pipeline/egopressurediff.h"
#include "pressure/hand_template.h"
#include "scheduler/animatelcm.h"
#include "scheduler/euler.h"
#include "scheduler/sampler.h"
#include "unet3d/unet_config.h"
#include "vae/vae_config.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  const std::string text = fuzz::as_string(data, size);
  // Through the files, as the runtime reads them (parse errors included) ...
  const std::string path = fuzz::write_scratch("config.json", text);
  fuzz::expect_only_egopd_errors([&] { (void)Config::load(path); });
  fuzz::expect_only_egopd_errors([&] { (void)load_sampler(path); });
  fuzz::expect_only_egopd_errors([&] { (void)ClipImageNormalization::load(path); });
  fuzz::expect_only_egopd_errors([&] { (void)HandTemplate::load(path); });
  // ... and every reader on a parsed document.
  nlohmann::json j;
  try {
    j = parse_json(text);
  } catch (const nlohmann::json::exception&) {  // a syntax error, or a number too large for a double (out_of_range)
    return 0;
  }
  const Config c(j, "fuzz/config.json");
  fuzz::expect_only_egopd_errors([&] { (void)UNetConfig::from(c); });
  fuzz::expect_only_egopd_errors([&] { (void)VaeConfig::from(c); });
  fuzz::expect_only_egopd_errors([&] { (void)read_clip_encoder_config(c, true); });
  fuzz::expect_only_egopd_errors([&] { (void)read_clip_encoder_config(c, false); });
  fuzz::expect_only_egopd_errors([&] { (void)ClipVisionConfig::from_config(c); });
  fuzz::expect_only_egopd_errors([&] { (void)MaskEncoderConfig::from(c); });
  fuzz::expect_only_egopd_errors([&] { (void)read_model_defaults(c); });
  fuzz::expect_only_egopd_errors([&] {
    EulerSampler s(c);
    s.set_timesteps(4);
  });
  fuzz::expect_only_egopd_errors([&] {
    AnimateLcmSampler s(c);
    s.set_timesteps(4);
  });
  fuzz::expect_only_egopd_errors([&] { (void)HandTemplate::parse(j, "fuzz/template.json"); });
  return 0;
}
