#pragma once
// Options shared by `egopd predict` and `egopd counterfactual`.
#include "cli/args.h"
#include "pipeline/predict_run.h"

namespace egopd {

// Reads every common option (the caller reads its own extras, then calls a.finish()).
PredictOptions read_predict_options(const Args& a);

}  // namespace egopd
