// `egopd forward --case DIR --output FILE`: run one golden case and write its outputs.
#include <cstdio>

#include "cli/commands.h"
#include "core/error.h"
#include "core/golden.h"
#include "pipeline/case_registry.h"

namespace egopd {

int cmd_forward(const Args& a) {
  const std::string dir = a.require("case");
  const std::string output = a.require("output");
  const bool check = a.flag("check");
  a.finish();
  GoldenCase c = load_golden_case(dir);
  CaseRunner run = find_case_runner(c.component);
  if (!run) {
    std::string known;
    for (const auto& k : case_components()) known += (known.empty() ? "" : ", ") + k;
    throw Error(dir + "/case.json: unknown or unsupported component '" + c.component + "' (supported: " + known + ")");
  }
  CaseOutputs out = run(c);
  write_case_outputs(output, out);
  if (!check) return 0;
  bool all = true;
  std::printf("case %s (%s)\n", c.name.c_str(), c.component.c_str());
  for (const auto& r : compare_case_outputs(c, out)) {
    all = all && r.ok;
    std::printf("  %-28s %-5s max_abs %.3e (<= %.3e)  rel_l2 %.3e (<= %.3e) %s\n", r.name.c_str(), r.ok ? "ok" : "FAIL",
                r.max_abs, r.tol_max_abs, r.rel_l2, r.tol_rel_l2, r.message.c_str());
  }
  std::printf("%s\n", all ? "PASS" : "FAIL");
  return all ? 0 : 1;
}

}  // namespace egopd
