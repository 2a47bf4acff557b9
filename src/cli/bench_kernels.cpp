// `egopd bench gemm` and `egopd bench conv2d` (placeholder until the kernel benchmarks land).
#include "cli/commands.h"
#include "core/error.h"

namespace egopd {

int bench_gemm(const Args& a) { throw Error("bench gemm: not implemented yet"); }
int bench_conv2d(const Args& a) { throw Error("bench conv2d: not implemented yet"); }

}  // namespace egopd
