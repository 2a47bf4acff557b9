#pragma once
// The instruction sets of this folder's files. Natively AVX-512 F/BW/VL/DQ with AVX2, FMA and F16C, enabled from
// here to the end of the including file (they are only called after the run-time CPU check), and AVX512-BF16 /
// AVX512-VNNI per function (EGOPD_TARGET_BF16, EGOPD_TARGET_VNNI). In a build configured with
// -DEGOPD_EMULATE_AVX512=ON the same intrinsics are portable code (emulated.h), so that the avx512 path's code is
// tested on CPUs without AVX-512. Include right after the file's standard includes.
#if defined(EGOPD_EMULATE_AVX512)
#include "core/kernels/avx512/emulated.h"
#define EGOPD_TARGET_BF16
#define EGOPD_TARGET_VNNI
#else
#pragma GCC target("avx512f,avx512bw,avx512vl,avx512dq,avx2,fma,f16c")
#include <immintrin.h>
#define EGOPD_TARGET_BF16 __attribute__((target("avx512bf16")))
#define EGOPD_TARGET_VNNI __attribute__((target("avx512vnni")))
#endif
