#pragma once
// The kernel sets of the element-wise ops and norms (elementwise.cpp, norm.cpp): a portable one, then one per SIMD
// folder of this architecture, each in the folder's namespace: avx2 and avx512 (kernels/avx2/, kernels/avx512/:
// the avx2 and avx512 paths) on x86-64, neon (kernels/neon/) on AArch64. EGOPD_FOR_EACH_SIMD_NS(M) expands M(ns)
// for each of those namespaces in that order, and kernel_set_index() is the index of the path in use in the list
// {portable, EGOPD_FOR_EACH_SIMD_NS(...)}.
#include "core/cpu.h"

#if defined(__aarch64__)
#define EGOPD_FOR_EACH_SIMD_NS(M) M(neon)
#else
#define EGOPD_FOR_EACH_SIMD_NS(M) M(avx2) M(avx512)
#endif

namespace egopd {

inline int kernel_set_index() {
#if defined(__aarch64__)
  return use_simd() ? 1 : 0;
#else
  const KernelPath p = kernel_path();
  return p == KernelPath::Avx512 ? 2 : p == KernelPath::Avx2 ? 1 : 0;
#endif
}

}  // namespace egopd
