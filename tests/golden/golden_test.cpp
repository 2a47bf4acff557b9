// Every golden case in tests/data/golden runs through the same runner `egopd forward` uses and is compared with
// its expected outputs exactly as compare.py does (max_abs and rel_l2 within the case's tolerance; ids exact),
// on every kernel path this CPU supports, at 1 and at 2 threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "core/cpu.h"
#include "core/golden.h"
#include "core/threading.h"
#include "pipeline/case_registry.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;

// Components whose runtime support has not landed yet. The test below fails if a component listed here gains a
// runner (remove it from this list then) or if a case's component is neither runnable nor listed.
const std::set<std::string> kPendingComponents = {};

std::vector<std::string> case_dirs() {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(fs::path(EGOPD_TEST_DATA) / "data" / "golden"))
    if (e.is_directory() && fs::exists(e.path() / "case.json")) v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

class GoldenCaseTest : public ::testing::TestWithParam<std::string> {};

TEST_P(GoldenCaseTest, MatchesExpectedOnEveryKernelPathAtOneAndTwoThreads) {
  const std::string dir = (fs::path(EGOPD_TEST_DATA) / "data" / "golden" / GetParam()).string();
  GoldenCase c = load_golden_case(dir);
  CaseRunner run = find_case_runner(c.component);
  if (!run) {
    ASSERT_TRUE(kPendingComponents.count(c.component)) << "no runner for component " << c.component;
    GTEST_SKIP() << "component " << c.component << " is not implemented yet";
  }
  const KernelPath before = kernel_path();
  for (KernelPath path : supported_kernel_paths())
    for (int threads : {1, 2}) {
      set_kernel_path(path);
      set_num_threads(threads);
      CaseOutputs out = run(c);
      for (const auto& r : compare_case_outputs(c, out)) {
        EXPECT_TRUE(r.ok) << c.name << " (" << kernel_path_name(path) << ", " << threads << " threads): " << r.name
                          << " max_abs " << r.max_abs << " (tol " << r.tol_max_abs << ") rel_l2 " << r.rel_l2
                          << " (tol " << r.tol_rel_l2 << ") " << r.message;
      }
    }
  set_kernel_path(before);
  set_num_threads(0);
}

INSTANTIATE_TEST_SUITE_P(Cases, GoldenCaseTest, ::testing::ValuesIn(case_dirs()),
                         [](const auto& info) { return info.param; });

TEST(GoldenRegistry, PendingListIsCurrent) {
  for (const auto& comp : case_components())
    EXPECT_FALSE(kPendingComponents.count(comp)) << comp << " has a runner now: remove it from kPendingComponents";
}

}  // namespace
}  // namespace egopd
