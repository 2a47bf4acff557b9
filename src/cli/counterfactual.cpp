// `egopd counterfactual`: the same clip and seed under prompt variants of one attribute (egopressurediff.md §9).
#include "cli/commands.h"
#include "cli/predict_options.h"

namespace egopd {

int cmd_counterfactual(const Args& a) {
  const PredictOptions o = read_predict_options(a);
  const VarySpec vary = parse_vary(a.require("vary"));
  a.finish();
  return run_with_library(o, &vary);
}

}  // namespace egopd
