#pragma once
#include <cstddef>
#include <cstdint>

#if defined(__SANITIZE_ADDRESS__)
#define EGOPD_ADDRESS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define EGOPD_ADDRESS_SANITIZER 1
#endif
#endif

namespace egopd {
uint64_t peak_rss_bytes();     // VmHWM of this process
uint64_t current_rss_bytes();  // VmRSS
// Bytes the heap has handed out and not taken back: AddressSanitizer's allocator in sanitizer builds (whose resident
// set also holds its quarantine of freed blocks), glibc's count over all arenas otherwise; 0 where neither reports.
uint64_t heap_in_use_bytes();
// Restarts VmHWM at the current RSS (Linux /proc/self/clear_refs), so peak_rss_bytes() reports the peak of what runs
// next: per-stage peaks. Returns false where the kernel does not support it.
bool reset_peak_rss();
// Gives the whole pages inside [p, p + bytes) of private anonymous memory back to the system. Only for memory that
// is never read again before it is freed: those pages read back as zeros.
void discard_pages(void* p, size_t bytes);

// 64-byte aligned from the system (bytes a multiple of 64), uninitialised; an Error naming the size when memory runs
// out. Free with std::free. From 4 MiB on, 2 MiB aligned and marked for transparent huge pages (memory.cpp; not with
// EGOPD_HUGE_PAGES=0).
void* aligned_alloc_checked(size_t bytes);
// Whether aligned_alloc_checked asks for huge pages: EGOPD_HUGE_PAGES 1 (default) or 0, read once; an Error naming the
// variable for any other value.
bool huge_pages_enabled();

// Grow-only 64-byte aligned float buffer (packing and transform scratch of the kernels, one per thread: OpenMP
// threads persist, so it is allocated once). get(n) keeps the contents only while n does not grow.
class AlignedScratch {
 public:
  AlignedScratch() = default;
  AlignedScratch(const AlignedScratch&) = delete;
  AlignedScratch& operator=(const AlignedScratch&) = delete;
  ~AlignedScratch();
  float* get(size_t floats);  // an Error naming the size when memory runs out

 private:
  float* p_ = nullptr;
  size_t n_ = 0;
};
}  // namespace egopd
