#include "core/cpu.h"

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

#include <cstdlib>
#include <cstring>

namespace egopd {

static int g_force_portable = -1;  // -1: read EGOPD_PORTABLE once

bool cpu_has_avx2_fma_f16c() {
#if defined(__x86_64__) || defined(__i386__)
  static const bool ok = [] {
    __builtin_cpu_init();
    // F16C from CPUID leaf 1 (ECX bit 29): not every compiler's __builtin_cpu_supports knows "f16c".
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    const bool f16c = __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & (1u << 29));
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && f16c;
  }();
  return ok;
#else
  return false;
#endif
}

void set_force_portable(bool on) { g_force_portable = on ? 1 : 0; }

bool use_avx2() {
  if (g_force_portable < 0) {
    const char* e = std::getenv("EGOPD_PORTABLE");
    g_force_portable = (e && *e && std::strcmp(e, "0") != 0) ? 1 : 0;
  }
  return !g_force_portable && cpu_has_avx2_fma_f16c();
}

}  // namespace egopd
