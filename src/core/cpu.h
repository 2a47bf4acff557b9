#pragma once
// What the CPU offers (instruction sets, cache sizes, model name) and the kernel path chosen from it once at
// start-up: avx512 (F+BW+VL+DQ), avx2 (AVX2+FMA+F16C) or portable on x86-64, neon (Advanced SIMD, ARMv8.0-A) or
// portable on AArch64. EGOPD_KERNELS=avx512|avx2|neon|portable forces one (EGOPD_PORTABLE=1 is the older spelling
// of EGOPD_KERNELS=portable); forcing a path the CPU lacks is an error.
#include <cstdint>
#include <string>
#include <vector>

namespace egopd {

struct CpuInfo {
  std::string model;  // brand string, e.g. "AMD EPYC 9R14 96-Core Processor" (x86, macOS)
  // The core: on x86 the CPUID family and model and, for AMD, the generation ("family 25 model 17, Zen 4"; virtual
  // CPUs often report a bare "AMD EPYC" for several generations); on AArch64 Linux the core named by MIDR_EL1
  // ("Arm Neoverse N1") when known.
  std::string core;
  std::string description() const;  // "<model> (<core>)", "unknown" when nothing is known
  bool avx2_fma_f16c = false;
  bool avx512 = false;       // F + BW + VL + DQ, with the OS saving the ZMM state
  bool avx512_bf16 = false;  // vdpbf16ps
  bool avx512_vnni = false;  // vpdpbusd
  bool neon = false;         // AArch64 Advanced SIMD (every AArch64 CPU)
  bool neon_fp16 = false;    // ARMv8.2 FP16 arithmetic (HWCAP fphp + asimdhp); reported only
  bool neon_dotprod = false; // ARMv8.2 dot product (HWCAP asimddp): the int8 kernel (sdot)
  // Per-core data caches in bytes (0 when unknown; the kernels then assume 32 KiB / 512 KiB / 16 MiB).
  int64_t l1d = 0, l2 = 0, l3 = 0;
  // The sizes the kernels block for: the measured ones, or those assumed when unknown.
  int64_t l1d_bytes() const { return l1d > 0 ? l1d : int64_t(32) << 10; }
  int64_t l2_bytes() const { return l2 > 0 ? l2 : int64_t(512) << 10; }
};
const CpuInfo& cpu_info();
// CpuInfo::core of an x86 CPU from its CPUID leaf 1 signature (EAX) and vendor: "family 25 model 17, Zen 4".
std::string x86_core_name(uint32_t signature, bool amd);

enum class KernelPath : uint8_t { Portable, Avx2, Avx512, Neon };

const char* kernel_path_name(KernelPath p);      // "portable", "avx2", "avx512", "neon"
std::string kernel_path_features(KernelPath p);  // "avx512f+bw+vl+dq", "avx2+fma+f16c", "neon (asimd)", "scalar"
bool kernel_path_supported(KernelPath p);
std::vector<KernelPath> supported_kernel_paths();  // every path this CPU runs, best last
KernelPath kernel_path();                          // the path in use
// Use path p from now on (tests and benchmarks); an Error when the CPU lacks it. Not thread-safe: call it
// between kernel calls, never during one.
void set_kernel_path(KernelPath p);

// A SIMD path is in use: the element-wise, norm and attention kernels of this architecture's SIMD folders (avx2/
// and avx512/ on x86-64, neon/ on AArch64) apply.
inline bool use_simd() { return kernel_path() != KernelPath::Portable; }

}  // namespace egopd
