#pragma once
// EGOPD_SIMD_NS: the namespace of this architecture's SIMD kernels for element-wise ops and norms, used when
// use_simd(): avx2 (kernels/avx2/, x86-64: the avx2 and avx512 paths) or neon (kernels/neon/, AArch64).
#if defined(__aarch64__)
#define EGOPD_SIMD_NS neon
#else
#define EGOPD_SIMD_NS avx2
#endif
