// Golden-case runners: `clip_vision` (pixel_values -> last_hidden_state, pooler_output, image_embeds) and
// `image_preprocess` (image in [-1,1] -> pixel_values).
#include <filesystem>

#include "clip_image/clip_vision.h"
#include "clip_image/svd_preprocess.h"
#include "core/golden.h"

namespace egopd {

CaseOutputs run_clip_vision_case(const GoldenCase& c) {
  const ClipVisionModelWithProjection model = ClipVisionModelWithProjection::load_dir(c.model_dir());
  ClipVisionOutput r = model.forward(c.input("pixel_values"));
  CaseOutputs out;
  out.tensors["last_hidden_state"] = r.last_hidden_state;
  out.tensors["pooler_output"] = r.pooler_output;
  out.tensors["image_embeds"] = r.image_embeds;
  return out;
}

CaseOutputs run_image_preprocess_case(const GoldenCase& c) {
  const auto norm =
      ClipImageNormalization::load((std::filesystem::path(c.model_dir()) / "preprocessor_config.json").string());
  CaseOutputs out;
  out.tensors["pixel_values"] = svd_clip_preprocess(c.input("image"), norm, 224);
  return out;
}

}  // namespace egopd
