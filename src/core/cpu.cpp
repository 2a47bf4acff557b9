#include "core/cpu.h"

#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#elif defined(__aarch64__) && defined(__linux__)
#include <sys/auxv.h>

#include <fstream>
#elif defined(__aarch64__) && defined(__APPLE__)
#include <sys/sysctl.h>
#endif

#include <algorithm>
#include <cstdlib>
#include <cstring>

#include "core/error.h"

namespace egopd {

namespace {

#if defined(__x86_64__) || defined(__i386__)
struct Regs {
  unsigned a = 0, b = 0, c = 0, d = 0;
};
Regs cpuid(unsigned leaf, unsigned sub = 0) {
  Regs r;
  if (!__get_cpuid_count(leaf, sub, &r.a, &r.b, &r.c, &r.d)) r = Regs{};
  return r;
}
unsigned max_leaf(unsigned base) {
  unsigned a = 0, b = 0, c = 0, d = 0;
  __cpuid(base, a, b, c, d);
  return a;
}
uint64_t xgetbv0() {
  unsigned lo = 0, hi = 0;
  __asm__ volatile("xgetbv" : "=a"(lo), "=d"(hi) : "c"(0));
  return (uint64_t(hi) << 32) | lo;
}

// Deterministic cache parameters (Intel leaf 4, AMD leaf 0x8000001D share the layout): size of each level's
// data or unified cache.
void read_caches(unsigned leaf, CpuInfo& ci) {
  for (unsigned i = 0; i < 16; ++i) {
    const Regs r = cpuid(leaf, i);
    const unsigned type = r.a & 0x1f;
    if (type == 0) break;
    if (type == 2) continue;  // instruction cache
    const unsigned level = (r.a >> 5) & 7;
    const int64_t size = int64_t((r.b >> 22) + 1) * (((r.b >> 12) & 0x3ff) + 1) * ((r.b & 0xfff) + 1) * (int64_t(r.c) + 1);
    if (level == 1) ci.l1d = size;
    if (level == 2) ci.l2 = size;
    if (level == 3) ci.l3 = size;
  }
}

CpuInfo detect() {
  CpuInfo ci;
  const unsigned max_std = max_leaf(0), max_ext = max_leaf(0x80000000u);
  const Regs l1 = cpuid(1);
  const bool osxsave = l1.c & (1u << 27);
  const uint64_t xcr0 = osxsave ? xgetbv0() : 0;
  const bool os_avx = (xcr0 & 0x6) == 0x6, os_avx512 = (xcr0 & 0xe6) == 0xe6;
  const Regs l7 = max_std >= 7 ? cpuid(7, 0) : Regs{};
  const Regs l7_1 = max_std >= 7 && l7.a >= 1 ? cpuid(7, 1) : Regs{};
  const bool fma = l1.c & (1u << 12), f16c = l1.c & (1u << 29), avx2 = l7.b & (1u << 5);
  ci.avx2_fma_f16c = os_avx && fma && f16c && avx2;
  const bool f = l7.b & (1u << 16), dq = l7.b & (1u << 17), bw = l7.b & (1u << 30), vl = l7.b & (1u << 31);
  ci.avx512 = ci.avx2_fma_f16c && os_avx512 && f && dq && bw && vl;
  ci.avx512_vnni = ci.avx512 && (l7.c & (1u << 11));
  ci.avx512_bf16 = ci.avx512 && (l7_1.a & (1u << 5));
#if defined(EGOPD_EMULATE_AVX512)
  // A test build: the avx512 path's instructions, BF16 and VNNI included, are portable code (kernels/avx512/isa.h).
  ci.avx512 = ci.avx512_vnni = ci.avx512_bf16 = ci.avx2_fma_f16c;
#endif
  if (max_ext >= 0x80000004u) {
    char brand[49] = {};
    for (unsigned i = 0; i < 3; ++i) {
      const Regs r = cpuid(0x80000002u + i);
      std::memcpy(brand + 16 * i, &r, 16);
    }
    ci.model = brand;
    ci.model.erase(0, ci.model.find_first_not_of(' '));
    ci.model.erase(ci.model.find_last_not_of(' ') + 1);
  }
  const Regs vendor = cpuid(0);
  const bool amd = vendor.b == 0x68747541u;  // "Auth"
  ci.core = x86_core_name(l1.a, amd);
  if (amd && max_ext >= 0x8000001Du)
    read_caches(0x8000001Du, ci);
  else if (max_std >= 4)
    read_caches(4, ci);
  return ci;
}
#elif defined(__aarch64__)
#if defined(__linux__)
std::string read_line(const std::string& path) {
  std::ifstream f(path);
  std::string s;
  std::getline(f, s);
  return s;
}

// "48K", "1024K", "8M" (sysfs cache sizes) in bytes; 0 when unreadable.
int64_t parse_size(const std::string& s) {
  char* end = nullptr;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (v <= 0 || !end) return 0;
  return *end == 'K' ? v * 1024 : *end == 'M' ? v * 1024 * 1024 : v;
}

// Core name from MIDR_EL1 (implementer and part number) for the cores egopd is tried on; empty otherwise.
std::string core_name(unsigned long midr) {
  const unsigned implementer = (midr >> 24) & 0xff, part = (midr >> 4) & 0xfff;
  if (implementer == 0x41) {  // Arm
    switch (part) {
      case 0xd03: return "Arm Cortex-A53";
      case 0xd05: return "Arm Cortex-A55";
      case 0xd08: return "Arm Cortex-A72";
      case 0xd0b: return "Arm Cortex-A76";
      case 0xd0c: return "Arm Neoverse N1";
      case 0xd40: return "Arm Neoverse V1";
      case 0xd41: return "Arm Cortex-A78";
      case 0xd42: return "Arm Cortex-A78AE";
      case 0xd49: return "Arm Neoverse N2";
      case 0xd4f: return "Arm Neoverse V2";
      default: break;
    }
  }
  return "";
}

CpuInfo detect() {
  CpuInfo ci;
  ci.neon = true;  // Advanced SIMD is mandatory in AArch64 Linux's ABI
  const unsigned long hw = getauxval(AT_HWCAP);
  // HWCAP bits of arch/arm64/include/uapi/asm/hwcap.h: fphp 9, asimdhp 10, asimddp 20.
  ci.neon_fp16 = (hw & (1ul << 9)) && (hw & (1ul << 10));
  ci.neon_dotprod = hw & (1ul << 20);
  const std::string cpu0 = "/sys/devices/system/cpu/cpu0/";
  const std::string midr = read_line(cpu0 + "regs/identification/midr_el1");
  if (!midr.empty()) ci.core = core_name(std::strtoul(midr.c_str(), nullptr, 16));
  for (int i = 0; i < 8; ++i) {
    const std::string dir = cpu0 + "cache/index" + std::to_string(i) + "/";
    const std::string type = read_line(dir + "type"), level = read_line(dir + "level");
    if (type.empty()) break;
    if (type == "Instruction") continue;
    const int64_t size = parse_size(read_line(dir + "size"));
    if (level == "1") ci.l1d = size;
    if (level == "2") ci.l2 = size;
    if (level == "3") ci.l3 = size;
  }
  return ci;
}
#elif defined(__APPLE__)
int64_t sysctl_int(const char* name) {
  int64_t v = 0;
  size_t len = sizeof(v);
  return sysctlbyname(name, &v, &len, nullptr, 0) == 0 ? v : 0;
}

CpuInfo detect() {
  CpuInfo ci;
  ci.neon = true;
  ci.neon_fp16 = sysctl_int("hw.optional.arm.FEAT_FP16") != 0;
  ci.neon_dotprod = sysctl_int("hw.optional.arm.FEAT_DotProd") != 0;
  char brand[128] = {};
  size_t len = sizeof(brand) - 1;
  if (sysctlbyname("machdep.cpu.brand_string", brand, &len, nullptr, 0) == 0) ci.model = brand;
  // The performance cores' caches (the kernels' threads run there).
  ci.l1d = sysctl_int("hw.perflevel0.l1dcachesize");
  ci.l2 = sysctl_int("hw.perflevel0.l2cachesize");
  return ci;
}
#else
CpuInfo detect() {
  CpuInfo ci;
  ci.neon = true;
  return ci;
}
#endif
#else
CpuInfo detect() { return CpuInfo{}; }
#endif

constexpr KernelPath kAllPaths[] = {KernelPath::Portable, KernelPath::Avx2, KernelPath::Avx512, KernelPath::Neon};

KernelPath best_path(const CpuInfo& ci) {
  if (ci.neon) return KernelPath::Neon;
#if !defined(EGOPD_EMULATE_AVX512)  // emulated, it runs only where asked for: EGOPD_KERNELS=avx512, per-path tests
  if (ci.avx512) return KernelPath::Avx512;
#endif
  if (ci.avx2_fma_f16c) return KernelPath::Avx2;
  return KernelPath::Portable;
}

KernelPath path_from_environment() {
  const CpuInfo& ci = cpu_info();
  if (const char* e = std::getenv("EGOPD_KERNELS"); e && *e) {
    for (KernelPath p : kAllPaths)
      if (std::strcmp(e, kernel_path_name(p)) == 0) {
        if (!kernel_path_supported(p))
          throw Error(std::string("EGOPD_KERNELS=") + e + ": this CPU does not support " + kernel_path_features(p));
        return p;
      }
    throw Error(std::string("EGOPD_KERNELS=") + e + ": unknown kernel path (avx512, avx2, neon or portable)");
  }
  const char* portable = std::getenv("EGOPD_PORTABLE");
  if (portable && *portable && std::strcmp(portable, "0") != 0) return KernelPath::Portable;
  return best_path(ci);
}

int g_path = -1;  // -1: not chosen yet

}  // namespace

const CpuInfo& cpu_info() {
  static const CpuInfo ci = detect();
  return ci;
}

namespace {

// AMD's model ranges of families 17h-1Ah (its processor programming references); nullptr for other families.
const char* amd_generation(unsigned family, unsigned model) {
  switch (family) {
    case 0x17: return model < 0x30 ? "Zen / Zen+" : "Zen 2";
    case 0x19:
      return (model >= 0x10 && model < 0x20) || (model >= 0x60 && model < 0x80) || model >= 0xa0 ? "Zen 4" : "Zen 3";
    case 0x1a: return "Zen 5";
    default: return nullptr;
  }
}

}  // namespace

std::string x86_core_name(uint32_t signature, bool amd) {
  // Display family and model: the extended fields count for base family 0xF (and the model's also for family 6).
  const unsigned base_family = (signature >> 8) & 0xf, base_model = (signature >> 4) & 0xf;
  const unsigned family = base_family == 0xf ? base_family + ((signature >> 20) & 0xff) : base_family;
  const unsigned model =
      base_family == 0xf || base_family == 6 ? (((signature >> 16) & 0xf) << 4) | base_model : base_model;
  const std::string name = "family " + std::to_string(family) + " model " + std::to_string(model);
  const char* generation = amd ? amd_generation(family, model) : nullptr;  // other vendors by number only
  return generation ? name + ", " + generation : name;
}

std::string CpuInfo::description() const {
  if (model.empty()) return core.empty() ? "unknown" : core;
  return core.empty() ? model : model + " (" + core + ")";
}

const char* kernel_path_name(KernelPath p) {
  switch (p) {
    case KernelPath::Avx512: return "avx512";
    case KernelPath::Avx2: return "avx2";
    case KernelPath::Neon: return "neon";
    default: return "portable";
  }
}

std::string kernel_path_features(KernelPath p) {
  switch (p) {
#if defined(EGOPD_EMULATE_AVX512)
    case KernelPath::Avx512: return "avx512f+bw+vl+dq emulated (SIMDe)";
#else
    case KernelPath::Avx512: return "avx512f+bw+vl+dq";
#endif
    case KernelPath::Avx2: return "avx2+fma+f16c";
    case KernelPath::Neon: {
      // The ARMv8.2 extensions are reported only: the kernels use the ARMv8.0-A instructions.
      std::string f = "neon (asimd)";
      if (cpu_info().neon_fp16) f += "+fp16";
      if (cpu_info().neon_dotprod) f += "+dotprod";
      return f;
    }
    default: return "scalar";
  }
}

bool kernel_path_supported(KernelPath p) {
  switch (p) {
    case KernelPath::Avx512: return cpu_info().avx512;
    case KernelPath::Avx2: return cpu_info().avx2_fma_f16c;
    case KernelPath::Neon: return cpu_info().neon;
    default: return true;
  }
}

std::vector<KernelPath> supported_kernel_paths() {
  std::vector<KernelPath> v;
  for (KernelPath p : kAllPaths)
    if (kernel_path_supported(p)) v.push_back(p);
  return v;
}

KernelPath kernel_path() {
  if (g_path < 0) g_path = int(path_from_environment());
  return KernelPath(g_path);
}

void set_kernel_path(KernelPath p) {
  if (!kernel_path_supported(p))
    throw Error(std::string("kernel path ") + kernel_path_name(p) + ": this CPU does not support " +
                kernel_path_features(p));
  g_path = int(p);
}

}  // namespace egopd
