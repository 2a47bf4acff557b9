// A sharded checkpoint's index JSON (weight_map -> shard file names), with one valid shard beside it.
#include "core/weights.h"
#include "fuzz_common.h"

namespace {
std::string tiny_shard() {
  const std::string header = R"({"a.weight":{"dtype":"F32","shape":[1],"data_offsets":[0,4]}})";
  std::string bytes(8, '\0');
  for (int i = 0; i < 8; ++i) bytes[size_t(i)] = char(uint64_t(header.size()) >> (8 * i));
  return bytes + header + std::string(4, '\0');
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  const std::string dir = (fuzz::scratch() / "sharded").string();
  std::filesystem::remove_all(dir);
  fuzz::write_scratch("sharded/m-00001-of-00001.safetensors", tiny_shard());
  fuzz::write_scratch("sharded/m.safetensors.index.json", fuzz::as_string(data, size));
  fuzz::expect_only_egopd_errors([&] {
    const WeightMap w = WeightMap::load_dir(dir, "m", "fuzz");
    for (const auto& k : w.keys()) (void)w.find(k)->to_f32();
  });
  return 0;
}
