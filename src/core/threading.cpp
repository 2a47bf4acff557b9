#include "core/threading.h"

#include <omp.h>

#include <cstdlib>
#include <fstream>
#include <set>
#include <string>
#include <thread>
#include <utility>

#include "core/error.h"

namespace egopd {

static int g_threads = 0;

int physical_cores() {
  std::set<std::pair<int, int>> cores;
  for (unsigned cpu = 0; cpu < 4096; ++cpu) {
    std::string base = "/sys/devices/system/cpu/cpu" + std::to_string(cpu) + "/topology/";
    std::ifstream c(base + "core_id"), p(base + "physical_package_id");
    if (!c || !p) break;
    int core = -1, pkg = -1;
    c >> core;
    p >> pkg;
    cores.insert({pkg, core});
  }
  int n = int(cores.size());
  if (n <= 0) n = int(std::thread::hardware_concurrency());
  return n > 0 ? n : 1;
}

static int env_threads() {
  const char* e = std::getenv("EGOPD_THREADS");
  if (!e || !*e) return 0;
  char* end = nullptr;
  long v = std::strtol(e, &end, 10);
  if (*end != '\0' || v < 1 || v > 1024) throw Error(std::string("EGOPD_THREADS='") + e + "' is not a thread count (1..1024)");
  return int(v);
}

void set_num_threads(int n) {
  if (n <= 0) n = env_threads();
  if (n <= 0) n = physical_cores();
  g_threads = n;
  omp_set_num_threads(n);
  omp_set_max_active_levels(1);  // no nested parallelism
}

int num_threads() {
  if (g_threads == 0) set_num_threads(0);
  return g_threads;
}

void init_threads_from_env() { set_num_threads(0); }

bool parallel_worth(int64_t n) { return n >= (1 << 15) && !omp_in_parallel(); }

}  // namespace egopd
