#pragma once
// Which function runs a golden case of each component (used by `egopd forward` and the golden tests).
#include <string>
#include <vector>

#include "core/golden.h"

namespace egopd {

using CaseRunner = CaseOutputs (*)(const GoldenCase&);
CaseRunner find_case_runner(const std::string& component);
std::vector<std::string> case_components();

}  // namespace egopd
