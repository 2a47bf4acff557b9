#include "core/finite_check.h"

#include <cstring>

#include "core/error.h"

namespace egopd {

int64_t count_non_finite(const float* data, int64_t n) {
  // Exponent all ones <=> NaN or Inf; integer compares vectorise where std::isfinite may not.
  int64_t bad = 0;
  for (int64_t i = 0; i < n; ++i) {
    uint32_t bits;
    std::memcpy(&bits, data + i, sizeof bits);
    bad += (bits & 0x7f800000u) == 0x7f800000u;
  }
  return bad;
}

void require_finite(const Tensor& t, const std::string& what) {
  const int64_t bad = count_non_finite(t.data(), t.numel());
  if (bad > 0)
    throw Error("non-finite values in " + what + ": " + std::to_string(bad) + " of " + std::to_string(t.numel()) +
                "; the model or its config is broken");
}

}  // namespace egopd
