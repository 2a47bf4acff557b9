#pragma once
// The C API's option structs checked and turned into the runs' options (predict_run.h). Every failure is one line
// naming the field or buffer; ArgumentError marks a caller's mistake (EGOPD_ERROR_ARGUMENT).
#include <string>

#include "core/error.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "egopd.h"
#include "pipeline/predict_run.h"

namespace egopd::api {

class ArgumentError : public Error {
 public:
  using Error::Error;
};

// A copy of the caller's struct: struct_size bytes of it over the defaults (an older, shorter struct keeps the
// defaults of the fields it lacks; a longer one is from a newer egopd and refused). NULL: the defaults.
egopd_load_options read_load_options(const egopd_load_options* o);
egopd_predict_options read_predict_options(const egopd_predict_options* o);

// The load options as the runs' options (model_dir "" = the built-in model); checks threads, size, precision.
PredictOptions load_predict_options(const char* model_dir, const egopd_load_options& o);
// The compute precision of the load options (NULL or "": fp32).
Precision load_precision(const egopd_load_options& o);
// The 3x3 convolution algorithm of the load options (NULL or "": EGOPD_CONV, else auto).
ConvAlgo load_conv(const egopd_load_options& o);
// The block cache limit of the load options in bytes (-1: EGOPD_BLOCK_CACHE_MB, else the default).
size_t load_block_cache_bytes(const egopd_load_options& o);
// One call's options over the model's: sampler, steps, seed, frames, size, guidance, paths; range-checked with the
// egopd predict options' bounds and wording.
PredictOptions call_predict_options(const PredictOptions& load, const egopd_predict_options& o);
// The clip of a call: video or frame buffers (checked against their sizes), masks, prompt or metadata fields.
ClipSource call_clip_source(const egopd_predict_options& o, const PredictOptions& po, const RunHooks& log);
// egopd_counterfactual's field and values.
VarySpec call_vary_spec(const char* field, const char* const* values, size_t num_values);

}  // namespace egopd::api
