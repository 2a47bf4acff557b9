#pragma once
// Non-finite guards: one pass over a tensor after each stage that could turn a broken model or config into NaN/Inf
// (cheap next to the stage itself), so a run is either right or fails with one line naming where it broke.
#include <cstdint>
#include <string>

#include "core/tensor.h"

namespace egopd {

// Number of NaN and ±Inf values among data[0..n).
int64_t count_non_finite(const float* data, int64_t n);

// Throws "non-finite values in <what>; the model or its config is broken" (and how many) when `t` holds any.
void require_finite(const Tensor& t, const std::string& what);

}  // namespace egopd
