// Winograd transforms on the neon path: the lane loops of winograd_transforms.h (Advanced SIMD is part of every
// AArch64 target), 12 lanes (the NR of the NEON GEMM; 8 filter lanes, its MR).
#include "core/kernels/gemm_internal.h"
#include "core/kernels/winograd_internal.h"
#include "core/kernels/winograd_transforms.h"

namespace egopd::wino_detail {

const WinogradKernels& winograd_kernels_neon() {
  static const WinogradKernels k = make_winograd_kernels<gemm_detail::kNrNeon, gemm_detail::kMrNeon>();
  return k;
}

}  // namespace egopd::wino_detail
