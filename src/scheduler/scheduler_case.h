#pragma once
// Golden-case runners of this component (registered in pipeline/case_registry.cpp).
#include "core/golden.h"

namespace egopd {

CaseOutputs run_rng_case(const GoldenCase& c);
CaseOutputs run_scheduler_euler_case(const GoldenCase& c);
CaseOutputs run_scheduler_lcm_case(const GoldenCase& c);

}  // namespace egopd
