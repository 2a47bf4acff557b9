#pragma once
// The single owner of parallelism: kernels parallelise internally with OpenMP using num_threads();
// model code never opens parallel regions around kernel calls (kernels run serially inside one).
#include <cstdint>

namespace egopd {

int physical_cores();          // from /sys topology; falls back to the logical CPU count
int num_threads();             // current setting
void set_num_threads(int n);   // n <= 0 means the default: EGOPD_THREADS, else physical cores
void init_threads_from_env();  // applies EGOPD_THREADS (called once by the CLI before option parsing)
// Whether a memory-bound loop over n floats should open a parallel region: n >= 2^15 (below that threads cost more
// than they save) and not already inside one.
bool parallel_worth(int64_t n);

}  // namespace egopd
