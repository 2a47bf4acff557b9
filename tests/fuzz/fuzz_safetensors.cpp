// safetensors files: header validation and every tensor read (to_f32 / to_i64), as the runtime and inspect do.
#include "core/safetensors.h"
#include "core/weights.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  const std::string path = fuzz::write_scratch("t.safetensors", fuzz::as_string(data, size));
  fuzz::expect_only_egopd_errors([&] {
    SafeTensorsFile f(path);
    for (const StoredTensor& t : f.tensors()) {
      fuzz::expect_only_egopd_errors([&] { (void)t.to_f32(); });
      fuzz::expect_only_egopd_errors([&] { (void)t.to_i64(); });
    }
    const WeightMap w = WeightMap::load_file(path, "fuzz");
    for (const auto& k : w.keys()) (void)w.aligned_data(*w.find(k));
  });
  return 0;
}
