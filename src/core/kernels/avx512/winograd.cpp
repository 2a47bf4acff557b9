// Winograd transforms on the avx512 path: the lane loops of winograd_transforms.h compiled for AVX-512, 32 lanes
// (the NR of the AVX-512 GEMM; 12 filter lanes, its MR).
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"

#include "core/kernels/avx512/isa.h"
#include "core/kernels/winograd_transforms.h"

namespace egopd::wino_detail {

const WinogradKernels& winograd_kernels_avx512() {
  static const WinogradKernels k = make_winograd_kernels<gemm_detail::kNrAvx512, gemm_detail::kMrAvx512>();
  return k;
}

}  // namespace egopd::wino_detail
