// Golden-case runner for component "mask_encoder".
#include "core/golden.h"
#include "mask_encoder/mask_encoder.h"

namespace egopd {

CaseOutputs run_mask_encoder_case(const GoldenCase& c) {
  MaskEncoder enc(c.model_dir());
  CaseOutputs out;
  out.tensors["features"] = enc.forward(c.input("mask"));
  return out;
}

}  // namespace egopd
