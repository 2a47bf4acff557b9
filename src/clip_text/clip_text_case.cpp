// Golden-case runners: `clip_text` (input_ids -> last_hidden_state, pooler_output) and `tokenizer`
// (args.texts -> input_ids_pad0, input_ids_pad_eos, lengths).
#include "clip_text/clip_text.h"
#include "clip_text/clip_tokenizer.h"
#include "core/error.h"
#include "core/golden.h"

namespace egopd {

CaseOutputs run_clip_text_case(const GoldenCase& c) {
  const ClipTextModel model = ClipTextModel::load_dir(c.model_dir());
  auto ids = c.id_inputs.find("input_ids");
  if (ids == c.id_inputs.end()) throw Error("case " + c.name + ": input tensor 'input_ids' is missing");
  ClipTextOutput r = model.forward(ids->second);
  CaseOutputs out;
  out.tensors["last_hidden_state"] = r.last_hidden_state;
  out.tensors["pooler_output"] = r.pooler_output;
  if (model.has_projection()) out.tensors["text_embeds"] = r.text_embeds;
  return out;
}

CaseOutputs run_tokenizer_case(const GoldenCase& c) {
  ClipTokenizer tok = ClipTokenizer::load_dir(c.model_dir());
  tok.set_context_length(c.args.get_int("context_length", 77));
  const std::vector<std::string> texts = c.args.get_string_list("texts");
  const int64_t n = int64_t(texts.size()), len = tok.context_length();
  IdTensor pad0{Shape{n, len}, {}}, pad_eos{Shape{n, len}, {}}, lengths{Shape{n}, {}};
  for (const auto& text : texts) {
    // The two padding conventions (open_clip: 0, HF CLIPTokenizer: <|endoftext|>) share everything else.
    const TokenizedText t = tok.encode(text, 0);
    pad0.values.insert(pad0.values.end(), t.ids.begin(), t.ids.end());
    for (int64_t j = 0; j < len; ++j) pad_eos.values.push_back(j < t.length ? t.ids[size_t(j)] : tok.eos_id());
    lengths.values.push_back(t.length);
  }
  CaseOutputs out;
  out.ids["input_ids_pad0"] = pad0;
  out.ids["input_ids_pad_eos"] = pad_eos;
  out.ids["lengths"] = lengths;
  return out;
}

}  // namespace egopd
