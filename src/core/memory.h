#pragma once
#include <cstddef>
#include <cstdint>

namespace egopd {
uint64_t peak_rss_bytes();     // VmHWM of this process
uint64_t current_rss_bytes();  // VmRSS
// Restarts VmHWM at the current RSS (Linux /proc/self/clear_refs), so peak_rss_bytes() reports the peak of what runs
// next: per-stage peaks. Returns false where the kernel does not support it.
bool reset_peak_rss();
// Gives the whole pages inside [p, p + bytes) of private anonymous memory back to the system. Only for memory that
// is never read again before it is freed: those pages read back as zeros.
void discard_pages(void* p, size_t bytes);
}  // namespace egopd
