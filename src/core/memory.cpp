#include "core/memory.h"

#include <sys/mman.h>
#if !EGOPD_ADDRESS_SANITIZER && defined(__GLIBC__)
#include <malloc.h>
#endif
#include <unistd.h>

#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <string>

#include "core/error.h"

#if EGOPD_ADDRESS_SANITIZER
// From the sanitizer runtime (its header, sanitizer/allocator_interface.h, is not installed with every compiler).
extern "C" size_t __sanitizer_get_current_allocated_bytes();
#endif

namespace egopd {

static uint64_t status_kb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::string f = std::string(field) + ":";
  while (std::getline(in, line))
    if (line.rfind(f, 0) == 0) return std::stoull(line.substr(f.size())) * 1024;
  return 0;
}

uint64_t peak_rss_bytes() { return status_kb("VmHWM"); }
uint64_t current_rss_bytes() { return status_kb("VmRSS"); }

uint64_t heap_in_use_bytes() {
#if EGOPD_ADDRESS_SANITIZER
  return __sanitizer_get_current_allocated_bytes();
#elif defined(__GLIBC__)
  const struct mallinfo2 m = ::mallinfo2();
  return uint64_t(m.uordblks) + uint64_t(m.hblkhd);  // in arenas + in blocks of their own mapping
#else
  return 0;
#endif
}

bool reset_peak_rss() {
  std::ofstream out("/proc/self/clear_refs");
  out << "5";
  out.flush();
  return bool(out);
}

void discard_pages(void* p, size_t bytes) {
  const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
  const uintptr_t begin = (reinterpret_cast<uintptr_t>(p) + page - 1) / page * page;
  const uintptr_t end = (reinterpret_cast<uintptr_t>(p) + bytes) / page * page;
  if (end > begin) ::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_DONTNEED);
}

namespace {

// Buffers of 4 MiB and more start on a 2 MiB boundary, span whole 2 MiB units and ask for transparent huge pages:
// their first writes then fault once per 2 MiB instead of once per 4 KiB page. On the Zen 5 virtual machines of
// BENCHMARKS.md (forty-fifth session) a fault costs ~10 us: VAE decode 16 x 256x256 24.8 -> 20.3 s (648 000 -> 11 600
// faults), at the same peak RSS. A hint only: where the kernel gives none (transparent_hugepage "never", or no free
// huge page), 4 KiB pages as before.
constexpr size_t kHugePageBytes = size_t(2) << 20;
constexpr size_t kHugePageMinBytes = size_t(4) << 20;

}  // namespace

bool huge_pages_enabled() {
  static const bool on = [] {
    const char* e = std::getenv("EGOPD_HUGE_PAGES");
    if (!e || std::string(e) == "1") return true;
    if (std::string(e) == "0") return false;
    throw Error(std::string("EGOPD_HUGE_PAGES='") + e + "': expected 0 or 1");
  }();
  return on;
}

void* aligned_alloc_checked(size_t bytes) {
  const bool huge = bytes >= kHugePageMinBytes && huge_pages_enabled();
  const size_t whole = huge ? (bytes + kHugePageBytes - 1) / kHugePageBytes * kHugePageBytes : bytes;
  void* p = std::aligned_alloc(huge ? kHugePageBytes : 64, whole);
  if (!p) throw Error("out of memory allocating " + std::to_string(bytes) + " bytes");
#if defined(MADV_HUGEPAGE)
  if (huge) ::madvise(p, whole, MADV_HUGEPAGE);
#endif
  return p;
}

AlignedScratch::~AlignedScratch() { std::free(p_); }

float* AlignedScratch::get(size_t floats) {
  if (floats > n_) {
    std::free(p_);
    p_ = nullptr;
    n_ = 0;
    const size_t bytes = (floats * sizeof(float) + 63) / 64 * 64;
    p_ = static_cast<float*>(aligned_alloc_checked(bytes));
    n_ = bytes / sizeof(float);
  }
  return p_;
}

}  // namespace egopd
