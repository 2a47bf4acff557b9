// A golden case folder's case.json (read by `egopd forward --case`).
#include "core/golden.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  fuzz::write_scratch("case/case.json", fuzz::as_string(data, size));
  fuzz::expect_only_egopd_errors([&] {
    const GoldenCase c = load_golden_case((fuzz::scratch() / "case").string());
    (void)c.model_dir();
  });
  return 0;
}
