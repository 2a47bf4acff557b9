#pragma once
// `egopd-convert from-original`: Stability's single-file SVD checkpoint -> model directory (weights.md §4).
#include <string>

#include "convert/tensor_io.h"

namespace egopd {

struct FromOriginalOptions {
  std::string preset = "svd-xt";  // architecture of the checkpoint: "svd-xt" or "tiny" (egopd's small test model)
  WriteOptions write;
};

struct FromOriginalReport {
  size_t mapped = 0, dropped = 0;  // source tensors
  size_t written = 0;              // target tensors
};

// Maps every source tensor (keeping its dtype), checks each component's key set and shapes against the model
// classes built from the generated configs, then writes unet/, vae/, image_encoder/ with configs, scheduler/,
// feature_extractor/ and model_index.json. Unmapped source keys or missing/unexpected targets are one error that
// lists them; nothing is written then.
FromOriginalReport convert_from_original(const std::string& source, const std::string& out_dir,
                                         const FromOriginalOptions& options);

}  // namespace egopd
