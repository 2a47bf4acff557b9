#pragma once
// CLIP byte-level BPE tokenizer (clip.md §5) reading Hugging Face files: vocab.json + merges.txt
// (+ tokenizer_config.json / special_tokens_map.json for pad_token and model_max_length).
// Text cleaning: Unicode NFC, whitespace collapse, Python-style full lower-case (no ftfy, no HTML unescape).
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

namespace egopd {

struct TokenizedText {
  std::vector<int64_t> ids;  // exactly context_length ids: BOS, content, EOS, then padding
  int64_t length = 0;        // ids before padding (BOS and EOS included; context_length when truncated)
  int64_t full_length = 0;   // BOS + all content ids + EOS, before truncation
  bool truncated = false;    // full_length > context_length: only the first context_length-2 content ids kept
};

class ClipTokenizer {
 public:
  // vocab: token string -> id; merges: pairs in rank order (rank = index).
  ClipTokenizer(std::unordered_map<std::string, int64_t> vocab,
                const std::vector<std::pair<std::string, std::string>>& merges);
  // Folder with vocab.json, merges.txt and optionally tokenizer_config.json / special_tokens_map.json.
  static ClipTokenizer load_dir(const std::string& dir);

  int64_t bos_id() const { return bos_id_; }
  int64_t eos_id() const { return eos_id_; }
  int64_t pad_id() const { return pad_id_; }
  int64_t context_length() const { return context_length_; }
  void set_pad_id(int64_t id) { pad_id_ = id; }
  void set_context_length(int64_t n);
  size_t vocab_size() const { return vocab_.size(); }
  size_t merge_count() const { return ranks_.size(); }

  // BOS + BPE ids + EOS, truncated to context_length (EOS kept last) and padded with pad_id (default: pad_id()).
  TokenizedText encode(const std::string& text) const { return encode(text, pad_id_); }
  TokenizedText encode(const std::string& text, int64_t pad_id) const;
  // Content ids only (no BOS/EOS, no truncation).
  std::vector<int64_t> content_ids(const std::string& text) const;
  // BPE symbols of one pre-token (e.g. "cocacola" -> {"cocacola</w>"}); a special token is returned unchanged.
  std::vector<std::string> bpe(const std::string& pre_token) const;

  // Cleaning: NFC, whitespace runs -> one space, strip, full lower-case. UTF-8 in and out.
  static std::string normalize(const std::string& text);
  // Pre-tokenisation of normalised text (clip.md §5.4). UTF-8 pieces.
  static std::vector<std::string> pre_tokenize(const std::string& normalized);

 private:
  std::unordered_map<std::string, int64_t> vocab_;
  std::unordered_map<std::string, int64_t> ranks_;  // "A B" -> rank
  int64_t bos_id_ = 49406, eos_id_ = 49407, pad_id_ = 49407;
  int64_t context_length_ = 77;
};

}  // namespace egopd
