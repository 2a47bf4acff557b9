// The tokenizer files (vocab.json, then "\n----\n", then merges.txt) and, with the shipped files, the text.
#include "clip_text/clip_tokenizer.h"
#include "fuzz_common.h"
#include "pipeline/synthetic_model.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace egopd;
  const std::string text = fuzz::as_string(data, size);
  const auto [vocab, merges] = fuzz::split2(text);
  fuzz::write_scratch("tok/vocab.json", vocab);
  fuzz::write_scratch("tok/merges.txt", merges);
  fuzz::expect_only_egopd_errors([&] {
    const ClipTokenizer t = ClipTokenizer::load_dir((fuzz::scratch() / "tok").string());
    (void)t.encode("a photo of a hand");
  });
  static const ClipTokenizer shipped = ClipTokenizer::load_dir(shipped_tokenizer_dir());
  fuzz::expect_only_egopd_errors([&] { (void)shipped.encode(text); });
  return 0;
}
