// Golden-case runners for components "unet" and "unet_pifr".
#include "core/golden.h"
#include "unet3d/unet.h"

namespace egopd {

CaseOutputs run_unet_case(const GoldenCase& c) {
  UNetSpatioTemporal unet(c.model_dir());
  const Tensor* text = c.has_input("text_tokens") ? &c.input("text_tokens") : nullptr;
  UNetConditioning cond = unet.prepare(c.input("encoder_hidden_states"), text);
  CaseOutputs out;
  out.tensors["sample"] =
      unet.forward(c.input("sample"), c.input("timestep")[0], c.input("added_time_ids"), cond);
  return out;
}

}  // namespace egopd
