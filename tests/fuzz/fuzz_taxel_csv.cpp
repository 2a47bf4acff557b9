// Taxel CSV files (frame,p0..p161 in N): predictions and ground truth of `egopd evaluate`.
#include "fuzz_common.h"
#include "pressure/taxel_csv.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  fuzz::expect_only_egopd_errors([&] {
    const TaxelSequence s = parse_taxel_csv(fuzz::as_string(data, size), "fuzz.csv");
    (void)format_taxel_csv(s);
  });
  return 0;
}
