// `egopd tokenize TEXT... [--tokenizer DIR]`: the CLIP BPE ids of each prompt (BOS, content, EOS, padding to 77).
#include <cstdio>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "clip_text/clip_tokenizer.h"
#include "core/error.h"
#include "core/json_text.h"
#include "pipeline/synthetic_model.h"

namespace egopd {

int cmd_tokenize(const Args& a) {
  const std::string dir = a.has("tokenizer") ? a.require("tokenizer") : shipped_tokenizer_dir();
  const bool json = a.flag("json");
  const bool has_pad = a.has("pad-id");
  const int64_t pad_override = a.get_int("pad-id", 0);
  const std::vector<std::string>& texts = a.positional();  // read before finish(), which rejects unread arguments
  a.finish();
  if (texts.empty()) throw Error("tokenize: give the text to tokenize (quote it)");

  ClipTokenizer tok = ClipTokenizer::load_dir(dir);
  if (has_pad) {
    if (pad_override < 0 || pad_override >= int64_t(tok.vocab_size()))
      throw Error("tokenize: --pad-id must be a vocabulary id (0.." + std::to_string(tok.vocab_size() - 1) + ")");
    tok.set_pad_id(pad_override);
  }
  for (const auto& text : texts) {
    const TokenizedText t = tok.encode(text);
    if (t.truncated)
      std::fprintf(stderr, "egopd: warning: the prompt has %lld tokens; truncated to %lld (EOS kept last)\n",
                   static_cast<long long>(t.full_length), static_cast<long long>(tok.context_length()));
    if (json) {
      nlohmann::ordered_json j;
      j["text"] = text;
      j["ids"] = t.ids;
      j["length"] = t.length;
      j["truncated"] = t.truncated;
      std::printf("%s\n", dump_json(j, -1, true).c_str());
    } else {
      std::string line;
      for (size_t i = 0; i < t.ids.size(); ++i) line.append(i ? " " : "").append(std::to_string(t.ids[i]));
      std::printf("%s\n", line.c_str());
    }
  }
  return 0;
}

}  // namespace egopd
