#include "clip_text/clip_tokenizer.h"

#include <unicode/locid.h>
#include <unicode/normalizer2.h>
#include <unicode/uchar.h>
#include <unicode/unistr.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include "core/error.h"
#include "core/json_text.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

const char* const kStartOfText = "<|startoftext|>";
const char* const kEndOfText = "<|endoftext|>";
// HF CLIPTokenizer / open_clip read at most 49152 - 256 - 2 merges.
constexpr size_t kMaxMerges = 49152 - 256 - 2;

// Python str.isspace(): the characters `" ".join(text.split())` collapses (not U+200B).
bool is_space(UChar32 c) {
  return (c >= 0x09 && c <= 0x0D) || (c >= 0x1C && c <= 0x20) || c == 0x85 || c == 0xA0 || c == 0x1680 ||
         (c >= 0x2000 && c <= 0x200A) || c == 0x2028 || c == 0x2029 || c == 0x202F || c == 0x205F || c == 0x3000;
}

bool is_letter(UChar32 c) {  // \p{L}
  switch (u_charType(c)) {
    case U_UPPERCASE_LETTER:
    case U_LOWERCASE_LETTER:
    case U_TITLECASE_LETTER:
    case U_MODIFIER_LETTER:
    case U_OTHER_LETTER:
      return true;
    default:
      return false;
  }
}

bool is_number(UChar32 c) {  // \p{N}
  switch (u_charType(c)) {
    case U_DECIMAL_DIGIT_NUMBER:
    case U_LETTER_NUMBER:
    case U_OTHER_NUMBER:
      return true;
    default:
      return false;
  }
}

void append_utf8(std::string& out, UChar32 c) {
  if (c < 0x80) {
    out += char(c);
  } else if (c < 0x800) {
    out += char(0xC0 | (c >> 6));
    out += char(0x80 | (c & 0x3F));
  } else if (c < 0x10000) {
    out += char(0xE0 | (c >> 12));
    out += char(0x80 | ((c >> 6) & 0x3F));
    out += char(0x80 | (c & 0x3F));
  } else {
    out += char(0xF0 | (c >> 18));
    out += char(0x80 | ((c >> 12) & 0x3F));
    out += char(0x80 | ((c >> 6) & 0x3F));
    out += char(0x80 | (c & 0x3F));
  }
}

std::vector<UChar32> code_points(const std::string& utf8) {
  const icu::UnicodeString s = icu::UnicodeString::fromUTF8(utf8);  // invalid bytes -> U+FFFD
  std::vector<UChar32> cps;
  for (int32_t i = 0; i < s.length(); i = s.moveIndex32(i, 1)) cps.push_back(s.char32At(i));
  return cps;
}

std::string to_utf8(const std::vector<UChar32>& cps, size_t begin, size_t end) {
  std::string s;
  for (size_t i = begin; i < end; ++i) append_utf8(s, cps[i]);
  return s;
}

// Case-insensitive match of an ASCII lower-case literal (the regex's IGNORECASE: simple case folding, under which
// U+017F long s and U+212A Kelvin sign also match 's' and 'k').
bool ci_equal(UChar32 c, char ascii) {
  if (u_tolower(c) == UChar32(ascii)) return true;
  return (ascii == 's' && c == 0x17F) || (ascii == 'k' && c == 0x212A);
}

size_t match_literal(const std::vector<UChar32>& cps, size_t i, const std::string& lit) {
  if (cps.size() - i < lit.size()) return 0;
  for (size_t j = 0; j < lit.size(); ++j)
    if (!ci_equal(cps[i + j], lit[j])) return 0;
  return lit.size();
}

// GPT-2 / CLIP byte -> unicode table (clip.md §5.2), each entry UTF-8 encoded.
const std::vector<std::string>& byte_symbols() {
  static const std::vector<std::string> table = [] {
    std::vector<std::string> t(256);
    int next = 256;
    for (int b = 0; b < 256; ++b) {
      const bool printable = (b >= 33 && b <= 126) || (b >= 161 && b <= 172) || (b >= 174 && b <= 255);
      append_utf8(t[size_t(b)], printable ? b : next++);
    }
    return t;
  }();
  return table;
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  if (!in) throw Error(p.string() + ": cannot open");
  try {
    return parse_json(in);
  } catch (const std::exception&) {
    throw Error(p.string() + ": not valid JSON");
  }
}

// pad_token is a string or an AddedToken object {"content": ...}; empty when absent.
std::string token_field(const nlohmann::json& j, const char* key) {
  if (!j.is_object() || !j.contains(key)) return "";
  const auto& v = j[key];
  if (v.is_string()) return v.get<std::string>();
  if (v.is_object() && v.contains("content") && v["content"].is_string()) return v["content"].get<std::string>();
  return "";
}

}  // namespace

ClipTokenizer::ClipTokenizer(std::unordered_map<std::string, int64_t> vocab,
                             const std::vector<std::pair<std::string, std::string>>& merges)
    : vocab_(std::move(vocab)) {
  for (size_t r = 0; r < merges.size() && r < kMaxMerges; ++r)
    ranks_.emplace(merges[r].first + " " + merges[r].second, int64_t(r));  // first occurrence keeps its rank
  auto special = [&](const char* name) {
    auto it = vocab_.find(name);
    if (it == vocab_.end()) throw Error(std::string("tokenizer: vocab.json has no ") + name + " token");
    return it->second;
  };
  bos_id_ = special(kStartOfText);
  eos_id_ = special(kEndOfText);
  pad_id_ = eos_id_;  // HF CLIPTokenizer default when no tokenizer config names a pad token
}

void ClipTokenizer::set_context_length(int64_t n) {
  if (n < 2) throw Error("tokenizer: context length must be at least 2, got " + std::to_string(n));
  context_length_ = n;
}

ClipTokenizer ClipTokenizer::load_dir(const std::string& dir) {
  const fs::path d(dir);
  if (!fs::is_directory(d)) throw Error("tokenizer: folder " + dir + " does not exist");
  const fs::path vocab_path = d / "vocab.json";
  const nlohmann::json vj = read_json(vocab_path);
  if (!vj.is_object()) throw Error(vocab_path.string() + ": expected an object of token -> id");
  std::unordered_map<std::string, int64_t> vocab;
  vocab.reserve(vj.size());
  for (auto it = vj.begin(); it != vj.end(); ++it) {
    if (!it->is_number_integer()) throw Error(vocab_path.string() + ": id of token " + it.key() + " is not an integer");
    vocab.emplace(it.key(), it->get<int64_t>());
  }
  // An empty vocabulary would still "tokenize" (every piece unknown): a broken download must fail instead.
  if (vocab.empty()) throw Error(vocab_path.string() + ": the vocabulary is empty");

  const fs::path merges_path = d / "merges.txt";
  std::ifstream in(merges_path);
  if (!in) throw Error(merges_path.string() + ": cannot open");
  std::vector<std::pair<std::string, std::string>> merges;
  std::string line;
  for (int64_t line_no = 1; std::getline(in, line) && merges.size() < kMaxMerges; ++line_no) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line_no == 1 && line.rfind("#version", 0) == 0) continue;
    if (line.empty()) continue;
    const size_t sp = line.find(' ');
    if (sp == std::string::npos || sp == 0 || sp + 1 == line.size() || line.find(' ', sp + 1) != std::string::npos)
      throw Error(merges_path.string() + ": line " + std::to_string(line_no) + " is not 'A B'");
    merges.emplace_back(line.substr(0, sp), line.substr(sp + 1));
  }
  // Without merges BPE splits every word into characters: a different tokenizer, not a degraded one.
  if (merges.empty()) throw Error(merges_path.string() + ": no merges (an empty or truncated merges.txt)");
  ClipTokenizer tok(std::move(vocab), merges);

  // pad_token / model_max_length from tokenizer_config.json, else special_tokens_map.json.
  std::string pad_token;
  int64_t max_length = 77;
  if (fs::exists(d / "tokenizer_config.json")) {
    const nlohmann::json tc = read_json(d / "tokenizer_config.json");
    pad_token = token_field(tc, "pad_token");
    // HF writes a huge sentinel when unlimited; the text tower has 77 positions.
    if (tc.is_object() && tc.contains("model_max_length") && tc["model_max_length"].is_number()) {
      const double m = tc["model_max_length"].get<double>();
      if (m >= 2 && m <= 77) max_length = int64_t(m);
    }
  }
  if (pad_token.empty() && fs::exists(d / "special_tokens_map.json"))
    pad_token = token_field(read_json(d / "special_tokens_map.json"), "pad_token");
  if (!pad_token.empty()) {
    auto it = tok.vocab_.find(pad_token);
    if (it == tok.vocab_.end()) throw Error("tokenizer: pad_token '" + pad_token + "' is not in vocab.json");
    tok.pad_id_ = it->second;
  }
  tok.set_context_length(max_length);
  return tok;
}

std::string ClipTokenizer::normalize(const std::string& text) {
  UErrorCode err = U_ZERO_ERROR;
  const icu::Normalizer2* nfc = icu::Normalizer2::getNFCInstance(err);
  if (U_FAILURE(err)) throw Error(std::string("tokenizer: Unicode NFC unavailable: ") + u_errorName(err));
  const icu::UnicodeString composed = nfc->normalize(icu::UnicodeString::fromUTF8(text), err);
  if (U_FAILURE(err)) throw Error(std::string("tokenizer: Unicode NFC failed: ") + u_errorName(err));

  // " ".join(text.split())
  icu::UnicodeString collapsed;
  bool pending_space = false;
  for (int32_t i = 0; i < composed.length(); i = composed.moveIndex32(i, 1)) {
    const UChar32 c = composed.char32At(i);
    if (is_space(c)) {
      pending_space = !collapsed.isEmpty();
      continue;
    }
    if (pending_space) collapsed.append(UChar32(' '));
    pending_space = false;
    collapsed.append(c);
  }
  // Full lower-case mapping (root locale): multi-character results and the final-sigma rule, like str.lower().
  collapsed.toLower(icu::Locale::getRoot());
  std::string out;
  collapsed.toUTF8String(out);
  return out;
}

std::vector<std::string> ClipTokenizer::pre_tokenize(const std::string& normalized) {
  static const std::string kSpecials[] = {kStartOfText, kEndOfText};
  static const std::string kContractions[] = {"'s", "'t", "'re", "'ve", "'m", "'ll", "'d"};
  const std::vector<UChar32> cps = code_points(normalized);
  std::vector<std::string> pieces;
  size_t i = 0;
  while (i < cps.size()) {
    if (is_space(cps[i])) {
      ++i;
      continue;
    }
    size_t n = 0;  // length of the match at i, alternatives in order
    for (const auto& s : kSpecials)
      if (!n) n = match_literal(cps, i, s);
    for (const auto& s : kContractions)
      if (!n) n = match_literal(cps, i, s);
    if (!n && is_letter(cps[i]))
      while (i + n < cps.size() && is_letter(cps[i + n])) ++n;
    if (!n && is_number(cps[i])) n = 1;
    if (!n)
      while (i + n < cps.size() && !is_space(cps[i + n]) && !is_letter(cps[i + n]) && !is_number(cps[i + n])) ++n;
    pieces.push_back(to_utf8(cps, i, i + n));
    i += n;
  }
  return pieces;
}

std::vector<std::string> ClipTokenizer::bpe(const std::string& pre_token) const {
  if (pre_token == kStartOfText || pre_token == kEndOfText) return {pre_token};
  // Byte-encode, one symbol per byte, "</w>" on the last symbol.
  std::vector<std::string> word;
  for (unsigned char b : pre_token) word.push_back(byte_symbols()[b]);
  if (word.empty()) return {};
  word.back() += "</w>";

  while (word.size() > 1) {
    int64_t best = std::numeric_limits<int64_t>::max();
    size_t best_at = 0;
    for (size_t j = 0; j + 1 < word.size(); ++j) {
      auto it = ranks_.find(word[j] + " " + word[j + 1]);
      if (it != ranks_.end() && it->second < best) {
        best = it->second;
        best_at = j;
      }
    }
    if (best == std::numeric_limits<int64_t>::max()) break;
    // Merge every non-overlapping occurrence of the best pair, left to right.
    const std::string first = word[best_at], second = word[best_at + 1];
    std::vector<std::string> merged;
    merged.reserve(word.size());
    for (size_t j = 0; j < word.size();) {
      if (j + 1 < word.size() && word[j] == first && word[j + 1] == second) {
        merged.push_back(first + second);
        j += 2;
      } else {
        merged.push_back(word[j]);
        j += 1;
      }
    }
    word.swap(merged);
  }
  return word;
}

std::vector<int64_t> ClipTokenizer::content_ids(const std::string& text) const {
  std::vector<int64_t> ids;
  for (const auto& piece : pre_tokenize(normalize(text)))
    for (const auto& sym : bpe(piece)) {
      auto it = vocab_.find(sym);
      ids.push_back(it == vocab_.end() ? eos_id_ : it->second);  // unknown symbol -> <|endoftext|>
    }
  return ids;
}

TokenizedText ClipTokenizer::encode(const std::string& text, int64_t pad_id) const {
  const std::vector<int64_t> content = content_ids(text);
  TokenizedText t;
  t.full_length = int64_t(content.size()) + 2;
  t.truncated = t.full_length > context_length_;
  const size_t keep = t.truncated ? size_t(context_length_ - 2) : content.size();
  t.ids.reserve(size_t(context_length_));
  t.ids.push_back(bos_id_);
  t.ids.insert(t.ids.end(), content.begin(), content.begin() + std::ptrdiff_t(keep));
  t.ids.push_back(eos_id_);
  t.length = int64_t(t.ids.size());
  t.ids.resize(size_t(context_length_), pad_id);
  return t;
}

}  // namespace egopd
