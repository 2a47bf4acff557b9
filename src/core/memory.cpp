#include "core/memory.h"

#include <fstream>
#include <string>

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

}  // namespace egopd
