// Winograd transforms on the avx2 path: the lane loops of winograd_transforms.h compiled for AVX2/FMA, 16 lanes
// (the NR of the AVX2 GEMM; 6 filter lanes, its MR).
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"

#pragma GCC target("avx2,fma,f16c")
#include "core/kernels/winograd_transforms.h"

namespace egopd::wino_detail {

const WinogradKernels& winograd_kernels_avx2() {
  static const WinogradKernels k = make_winograd_kernels<gemm_detail::kNrAvx2, gemm_detail::kMrAvx2>();
  return k;
}

}  // namespace egopd::wino_detail
