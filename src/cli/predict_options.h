#pragma once
// Options shared by `egopd predict` and `egopd counterfactual`.
#include "cli/args.h"
#include "pipeline/predict_run.h"

namespace egopd {

// Reads every common option (the caller reads its own extras, then calls a.finish()).
PredictOptions read_predict_options(const Args& a);
// Runs `egopd predict` (vary null) or `egopd counterfactual` through the C API (include/egopd.h); returns the exit
// status.
int run_with_library(const PredictOptions& o, const VarySpec* vary);

}  // namespace egopd
