#pragma once
#include <cstdint>

namespace egopd {
uint64_t peak_rss_bytes();     // VmHWM of this process
uint64_t current_rss_bytes();  // VmRSS
}  // namespace egopd
