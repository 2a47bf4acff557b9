#include "core/memory.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

namespace egopd {
namespace {

constexpr size_t kMiB = size_t(1) << 20;

// The VmFlags line of the mapping of /proc/self/smaps that holds p ("" if none).
std::string vm_flags_of(const void* p) {
  std::ifstream smaps("/proc/self/smaps");
  const uintptr_t a = reinterpret_cast<uintptr_t>(p);
  bool inside = false;
  for (std::string line; std::getline(smaps, line);) {
    uintptr_t lo = 0, hi = 0;
    char dash = 0;
    std::istringstream head(line);
    if (head >> std::hex >> lo >> dash >> hi && dash == '-' && line.find(':') > line.find(' ')) {
      inside = lo <= a && a < hi;
      continue;
    }
    if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return "";
}

// Whether this system's kernel offers transparent huge pages to madvise (not "never", and built in).
bool kernel_offers_huge_pages() {
  std::ifstream f("/sys/kernel/mm/transparent_hugepage/enabled");
  std::string s;
  std::getline(f, s);
  return s.find("[always]") != std::string::npos || s.find("[madvise]") != std::string::npos;
}

TEST(AlignedAlloc, SmallBuffersAre64ByteAligned) {
  for (size_t bytes : {size_t(64), size_t(4096), 4 * kMiB - 64}) {
    void* p = aligned_alloc_checked(bytes);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(p) % 64, 0u) << bytes;
    std::memset(p, 0x5a, bytes);
    std::free(p);
  }
}

TEST(AlignedAlloc, LargeBuffersStartOnHugePageBoundaries) {
  const size_t alignment = huge_pages_enabled() ? 2 * kMiB : 64;  // EGOPD_HUGE_PAGES=0: as small buffers
  for (size_t bytes : {4 * kMiB, 5 * kMiB + 64, 33 * kMiB}) {
    auto* p = static_cast<unsigned char*>(aligned_alloc_checked(bytes));
    EXPECT_EQ(reinterpret_cast<uintptr_t>(p) % alignment, 0u) << bytes;
    std::memset(p, 0x5a, bytes);  // every byte asked for is writable
    EXPECT_EQ(p[0], 0x5a);
    EXPECT_EQ(p[bytes - 1], 0x5a);
#if defined(__x86_64__) && defined(__linux__)
    // Natively (not under an emulator, which may ignore the advice) the mapping carries the advice: "hg" in VmFlags.
    if (huge_pages_enabled() && kernel_offers_huge_pages()) {
      EXPECT_NE(vm_flags_of(p).find(" hg"), std::string::npos) << vm_flags_of(p);
    }
#endif
    std::free(p);
  }
}

}  // namespace
}  // namespace egopd
