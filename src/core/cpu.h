#pragma once
// Run-time choice between the AVX2/FMA/F16C kernels and the portable ones.
namespace egopd {

bool cpu_has_avx2_fma_f16c();  // what the CPU supports
bool use_avx2();               // supported and not disabled (EGOPD_PORTABLE=1 or set_force_portable(true))
void set_force_portable(bool on);

}  // namespace egopd
