#include "pipeline/case_registry.h"

namespace egopd {

// Runners live beside their components (src/<component>/*_case.cpp).
// Add one declaration and one table row per component.
// -- declarations --
// -- end declarations --

namespace {
struct Entry {
  const char* component;
  CaseRunner run;
};
const Entry kRunners[] = {
    // -- table --
    {"", nullptr},
    // -- end table --
};
}  // namespace

CaseRunner find_case_runner(const std::string& component) {
  for (const auto& e : kRunners)
    if (e.run && component == e.component) return e.run;
  return nullptr;
}

std::vector<std::string> case_components() {
  std::vector<std::string> v;
  for (const auto& e : kRunners)
    if (e.run) v.push_back(e.component);
  return v;
}

}  // namespace egopd
