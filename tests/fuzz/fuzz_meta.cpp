// --meta files and manifest lines: prompt fields, the prompt built from them, and a one-line manifest.
#include <nlohmann/json.hpp>

#include "batch/manifest.h"
#include "fuzz_common.h"
#include "pipeline/prompt.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  const std::string text = fuzz::as_string(data, size);
  const std::string meta = fuzz::write_scratch("meta.json", text);
  fuzz::expect_only_egopd_errors([&] {
    const PromptFields f = load_prompt_fields(meta);
    (void)build_prompt(f);
  });
  const std::string manifest = fuzz::write_scratch("m.jsonl", text);
  fuzz::expect_only_egopd_errors([&] {
    const Manifest m = read_manifest(manifest);
    for (const ManifestClip& c : m.clips) (void)manifest_line(c);
  });
  return 0;
}
