// CLIP BPE tokenizer: cleaning, pre-tokenisation, ranked merges, assembly (BOS/EOS, truncation, padding) and the
// tokenizer config. Expected ids come from clip.md §5.7 or are derived by hand from vocab.json / merges.txt.
#include "clip_text/clip_tokenizer.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/error.h"

namespace egopd {
namespace {

namespace fs = std::filesystem;
using Ids = std::vector<int64_t>;

const std::string kTokenizerDir = std::string(EGOPD_TEST_DATA) + "/data/golden/tokenizer/model";

const ClipTokenizer& clip() {
  static const ClipTokenizer tok = ClipTokenizer::load_dir(kTokenizerDir);
  return tok;
}

Ids content(const std::string& text) { return clip().content_ids(text); }

TEST(ClipTokenizer, LoadsTheRealVocabulary) {
  EXPECT_EQ(clip().vocab_size(), 49408u);
  EXPECT_EQ(clip().merge_count(), 48894u);
  EXPECT_EQ(clip().bos_id(), 49406);
  EXPECT_EQ(clip().eos_id(), 49407);
  EXPECT_EQ(clip().pad_id(), 49407);  // tokenizer_config.json: pad_token <|endoftext|>
  EXPECT_EQ(clip().context_length(), 77);
}

TEST(ClipTokenizer, WorkedExamplesOfTheSpec) {
  const std::string prompt =
      "This video shows the action of picking up a CocaCola. The weight of the CocaCola is 355g, and its surface "
      "material is aluminum. The person performing the action is male, 25 years of age, weighing 74kg and having 25% "
      "body fat";
  const Ids expected = {49406, 589, 1455,  2665, 518,  1816, 539,  9545, 705,  320, 31248, 269,  518,  3868,
                        539,   518, 31248, 533,  274,  276,  276,  326,  267,  537, 902,   7744, 7118, 533,
                        15251, 269, 518,   2533, 5170, 518,  1816, 533,  2801, 267, 273,   276,  1151, 539,
                        805,   267, 24455, 278,  275,  7817, 537,  1977, 273,  276, 260,   1774, 5484, 49407};
  const TokenizedText t = clip().encode(prompt, 0);
  ASSERT_EQ(t.ids.size(), 77u);
  EXPECT_EQ(t.length, 56);
  EXPECT_FALSE(t.truncated);
  EXPECT_EQ(Ids(t.ids.begin(), t.ids.begin() + 56), expected);
  EXPECT_EQ(Ids(t.ids.begin() + 56, t.ids.end()), Ids(21, 0));

  const TokenizedText cat = clip().encode("a photo of a cat");
  EXPECT_EQ(Ids(cat.ids.begin(), cat.ids.begin() + 7), (Ids{49406, 320, 1125, 539, 320, 2368, 49407}));
  EXPECT_EQ(Ids(cat.ids.begin() + 7, cat.ids.end()), Ids(70, 49407));  // default pad = the config's <|endoftext|>
}

TEST(ClipTokenizer, EmptyAndWhitespaceOnlyGiveBosEos) {
  for (const std::string text : {"", " ", "   \t\n\r\f\v  ", "\u3000\u00a0\u2028"}) {
    const TokenizedText t = clip().encode(text, 0);
    EXPECT_EQ(t.length, 2) << text;
    EXPECT_EQ(t.ids[0], 49406);
    EXPECT_EQ(t.ids[1], 49407);
    EXPECT_EQ(Ids(t.ids.begin() + 2, t.ids.end()), Ids(75, 0));
  }
}

TEST(ClipTokenizer, NormalisationCollapsesWhitespaceAndLowerCases) {
  EXPECT_EQ(ClipTokenizer::normalize("  A\t\tPhoto \n of\u3000a\u00a0CAT  "), "a photo of a cat");
  // U+200B (zero width space) is not whitespace for str.split(): kept.
  EXPECT_EQ(ClipTokenizer::normalize("a\u200bb"), "a\u200bb");
  // NFC composes e + combining acute; lower-case is the full mapping (İ -> i + combining dot, final sigma).
  EXPECT_EQ(ClipTokenizer::normalize("cafe\u0301"), "caf\u00e9");
  EXPECT_EQ(ClipTokenizer::normalize("CAF\u00c9"), "caf\u00e9");
  EXPECT_EQ(ClipTokenizer::normalize("\u0130"), "i\u0307");
  EXPECT_EQ(ClipTokenizer::normalize("\u039f\u0394\u039f\u03a3"), "\u03bf\u03b4\u03bf\u03c2");  // ΟΔΟΣ -> οδος
  EXPECT_EQ(ClipTokenizer::normalize("\u03a3A"), "\u03c3a");                                    // not final
}

TEST(ClipTokenizer, AccentsAreTheSameComposedOrDecomposed) {
  EXPECT_EQ(content("cafe\u0301"), content("caf\u00e9"));
  EXPECT_EQ(content("CAF\u00c9"), content("caf\u00e9"));
  // é is two UTF-8 bytes (C3 A9 -> byte symbols Ã ©); the ids spell the word back.
  const Ids ids = content("caf\u00e9");
  ASSERT_FALSE(ids.empty());
  for (int64_t id : ids) EXPECT_NE(id, 49407);  // every BPE symbol is in the vocabulary
}

TEST(ClipTokenizer, PreTokenisation) {
  using V = std::vector<std::string>;
  EXPECT_EQ(ClipTokenizer::pre_tokenize("hello, world!! ...ok"), (V{"hello", ",", "world", "!!", "...", "ok"}));
  // Numbers are single characters; letters and digits split.
  EXPECT_EQ(ClipTokenizer::pre_tokenize("355g 3.14"), (V{"3", "5", "5", "g", "3", ".", "1", "4"}));
  // Contractions are their own pieces (first alternative wins), even without a word boundary.
  EXPECT_EQ(ClipTokenizer::pre_tokenize("don't we'll i'm 'sam"), (V{"don", "'t", "we", "'ll", "i", "'m", "'s", "am"}));
  // A punctuation run swallows an apostrophe that follows it.
  EXPECT_EQ(ClipTokenizer::pre_tokenize("!'s"), (V{"!'", "s"}));
  // Special tokens are matched literally; combining marks are not letters.
  EXPECT_EQ(ClipTokenizer::pre_tokenize("a<|endoftext|>b"), (V{"a", "<|endoftext|>", "b"}));
  EXPECT_EQ(ClipTokenizer::pre_tokenize("i\u0307x"), (V{"i", "\u0307", "x"}));
  // Non-Latin letters and other numbers (½ is No).
  EXPECT_EQ(ClipTokenizer::pre_tokenize("\u65e5\u672c 1\u00bd"), (V{"\u65e5\u672c", "1", "\u00bd"}));
}

TEST(ClipTokenizer, PunctuationAndNumbersHandDerived) {
  // Ids of single-character symbols "c</w>" as listed in clip.md §5.7.
  EXPECT_EQ(content("355"), (Ids{274, 276, 276}));  // "3</w>" "5</w>" "5</w>" (spec §5.7)
  EXPECT_EQ(content("25%"), (Ids{273, 276, 260}));  // "2</w>" "5</w>" "%</w>"
  EXPECT_EQ(content(","), (Ids{267}));
  EXPECT_EQ(content("a."), (Ids{320, 269}));
  EXPECT_EQ(content("<|startoftext|>"), (Ids{49406}));  // literal special token: its id, no BPE
}

TEST(ClipTokenizer, LongTextIsTruncatedWithEosLast) {
  std::string text;
  for (int i = 0; i < 100; ++i) text += "cat ";
  for (int64_t pad : {int64_t(0), int64_t(49407)}) {
    const TokenizedText t = clip().encode(text, pad);
    EXPECT_TRUE(t.truncated);
    EXPECT_EQ(t.full_length, 102);
    EXPECT_EQ(t.length, 77);
    ASSERT_EQ(t.ids.size(), 77u);
    EXPECT_EQ(t.ids.front(), 49406);
    EXPECT_EQ(t.ids.back(), 49407);
    for (size_t j = 1; j < 76; ++j) EXPECT_EQ(t.ids[j], 2368);  // "cat</w>"
  }
  // Exactly 75 content ids fit without truncation.
  std::string fits;
  for (int i = 0; i < 75; ++i) fits += "cat ";
  const TokenizedText f = clip().encode(fits);
  EXPECT_FALSE(f.truncated);
  EXPECT_EQ(f.length, 77);
  EXPECT_EQ(f.ids.back(), 49407);
}

// A hand-made vocabulary to pin the merge rules.
class TinyTokenizer : public ::testing::Test {
 protected:
  std::unordered_map<std::string, int64_t> vocab{
      {"a", 0},      {"b", 1},        {"a</w>", 2},           {"b</w>", 3},        {"ab", 4},
      {"ab</w>", 5}, {"abab</w>", 6}, {"<|startoftext|>", 7}, {"<|endoftext|>", 8}};
};

TEST_F(TinyTokenizer, LowestRankFirstAndEveryOccurrence) {
  const ClipTokenizer t(vocab, {{"a", "b"}, {"a", "b</w>"}, {"ab", "ab</w>"}});
  // a b a b</w> -> (rank 0) ab a b</w> -> (rank 1) ab ab</w> -> (rank 2) abab</w>
  EXPECT_EQ(t.bpe("abab"), (std::vector<std::string>{"abab</w>"}));
  // Only rank 0: every non-overlapping a·b merges, the final a·b</w> does not.
  const ClipTokenizer only0(vocab, {{"a", "b"}});
  EXPECT_EQ(only0.bpe("ababab"), (std::vector<std::string>{"ab", "ab", "a", "b</w>"}));
  EXPECT_EQ(only0.bpe("a"), (std::vector<std::string>{"a</w>"}));
  // A symbol missing from the vocabulary maps to <|endoftext|>.
  EXPECT_EQ(only0.content_ids("ababab"), (Ids{4, 4, 0, 3}));
  EXPECT_EQ(only0.content_ids("c"), (Ids{8}));
}

TEST_F(TinyTokenizer, VocabularyWithoutSpecialTokensIsAnError) {
  vocab.erase("<|endoftext|>");
  EXPECT_THROW(ClipTokenizer(vocab, {}), Error);
}

// Tokenizer folders written to a temporary directory.
class TokenizerDir : public ::testing::Test {
 protected:
  fs::path dir = fs::temp_directory_path() / ("egopd-tok-" + std::to_string(::getpid()));
  void SetUp() override {
    fs::create_directories(dir);
    fs::copy_file(kTokenizerDir + "/vocab.json", dir / "vocab.json");
    fs::copy_file(kTokenizerDir + "/merges.txt", dir / "merges.txt");
  }
  void TearDown() override { fs::remove_all(dir); }
  void write(const std::string& name, const std::string& text) { std::ofstream(dir / name) << text; }
};

TEST_F(TokenizerDir, PadTokenFromConfigOrDefault) {
  EXPECT_EQ(ClipTokenizer::load_dir(dir.string()).pad_id(), 49407);  // no config: HF default
  write("special_tokens_map.json", R"({"pad_token": {"content": "!", "lstrip": false}})");
  EXPECT_EQ(ClipTokenizer::load_dir(dir.string()).pad_id(), 0);  // SD-2 / OpenCLIP-H convention
  write("tokenizer_config.json", R"({"pad_token": "<|endoftext|>", "model_max_length": 77})");
  EXPECT_EQ(ClipTokenizer::load_dir(dir.string()).pad_id(), 49407);  // tokenizer_config.json wins
  write("tokenizer_config.json", R"({"pad_token": "<pad>"})");
  EXPECT_THROW(ClipTokenizer::load_dir(dir.string()), Error);
}

TEST_F(TokenizerDir, MissingOrMalformedFilesAreErrors) {
  write("merges.txt", "#version: 0.2\ni n\nbroken-line\n");
  try {
    ClipTokenizer::load_dir(dir.string());
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  fs::remove(dir / "vocab.json");
  EXPECT_THROW(ClipTokenizer::load_dir(dir.string()), Error);
  EXPECT_THROW(ClipTokenizer::load_dir((dir / "nope").string()), Error);
}

// An empty vocabulary or merges file is a broken download, not a tokenizer that splits into characters.
TEST_F(TokenizerDir, EmptyVocabularyOrMergesAreErrors) {
  write("merges.txt", "#version: 0.2\n\n");
  try {
    ClipTokenizer::load_dir(dir.string());
    FAIL() << "empty merges accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("merges.txt: no merges"), std::string::npos) << e.what();
  }
  fs::copy_file(kTokenizerDir + "/merges.txt", dir / "merges.txt", fs::copy_options::overwrite_existing);
  write("vocab.json", "{}");
  try {
    ClipTokenizer::load_dir(dir.string());
    FAIL() << "empty vocabulary accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("vocab.json: the vocabulary is empty"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace egopd
