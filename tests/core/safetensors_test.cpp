// safetensors reading (header validation, dtypes, alignment), writing (atomic, round trip), weight maps
// (shape-checked lookup, prefix views, unused keys, sharded checkpoints) and config access.
#include <gtest/gtest.h>

#include <cmath>
#include <unistd.h>

#include <cstring>
#include <functional>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "core/atomic_file.h"
#include "core/config.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "core/weights.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

class TempDir {
 public:
  TempDir() {
    path_ = fs::temp_directory_path() / ("egopd-st-" + std::to_string(::getpid()) + "-" + std::to_string(counter_++));
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }
  std::string path_str() const { return path_.string(); }

 private:
  fs::path path_;
  static inline int counter_ = 0;
};

// A raw safetensors file from a header string and data bytes.
void write_raw(const std::string& path, const std::string& header, const std::string& data) {
  std::ofstream out(path, std::ios::binary);
  uint64_t n = header.size();
  for (int i = 0; i < 8; ++i) out.put(char(n >> (8 * i)));
  out << header << data;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

TEST(SafeTensors, RoundTripAllDtypes) {
  TempDir d;
  Tensor a = Tensor::from({2, 3}, {1.5f, -2.0f, 0.0f, 3.25f, 65504.0f, -1e-7f});
  IdTensor ids{Shape{3}, {7, -1, 49407}};
  write_safetensors(d.file("x.safetensors"),
                    {to_write("a32", a), to_write("a16", a, DType::F16), to_write("abf", a, DType::BF16),
                     to_write("ids", ids)},
                    {{"format", "pt"}});
  SafeTensorsFile f(d.file("x.safetensors"));
  ASSERT_EQ(f.tensors().size(), 4u);
  EXPECT_EQ(f.metadata().at("format"), "pt");
  Tensor b = f.find("a32")->to_f32();
  for (int i = 0; i < 6; ++i) EXPECT_EQ(b[i], a[i]);
  Tensor h = f.find("a16")->to_f32();
  EXPECT_EQ(h[0], 1.5f);
  EXPECT_EQ(h[4], 65504.0f);                         // largest half
  EXPECT_EQ(h[5], half_to_float(float_to_half(-1e-7f)));  // subnormal half
  EXPECT_NEAR(h[5], -1e-7, 6e-8);
  Tensor bf = f.find("abf")->to_f32();
  EXPECT_EQ(bf[3], 3.25f);
  EXPECT_EQ(f.find("ids")->to_i64(), ids.values);
  EXPECT_EQ(f.find("missing"), nullptr);
  // the data section starts 8-byte aligned
  uint64_t n = 0;
  std::ifstream in(d.file("x.safetensors"), std::ios::binary);
  for (int i = 0; i < 8; ++i) n |= uint64_t(uint8_t(in.get())) << (8 * i);
  EXPECT_EQ((8 + n) % 8, 0u);
}

TEST(SafeTensors, ScalarAndEmptyTensors) {
  TempDir d;
  write_raw(d.file("s.safetensors"),
            R"({"s":{"dtype":"F32","shape":[],"data_offsets":[0,4]},"e":{"dtype":"F32","shape":[0,3],"data_offsets":[4,4]}})",
            std::string("\x00\x00\x80\x3f", 4));
  SafeTensorsFile f(d.file("s.safetensors"));
  EXPECT_EQ(f.find("s")->to_f32()[0], 1.0f);
  EXPECT_EQ(f.find("e")->numel(), 0);
}

TEST(SafeTensors, RejectsBadHeaders) {
  TempDir d;
  const std::string p = d.file("bad.safetensors");
  const std::string four(4, '\0');
  {
    std::ofstream out(p, std::ios::binary);
    out << "abc";
  }
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("too short"), std::string::npos);
  {
    std::ofstream out(p, std::ios::binary);
    uint64_t n = uint64_t(200) << 20;
    for (int i = 0; i < 8; ++i) out.put(char(n >> (8 * i)));
  }
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("over 100 MiB"), std::string::npos);
  {
    std::ofstream out(p, std::ios::binary);
    uint64_t n = 1000;
    for (int i = 0; i < 8; ++i) out.put(char(n >> (8 * i)));
    out << "{}";
  }
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("exceeds the file size"), std::string::npos);
  write_raw(p, "{not json", "");
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("not valid JSON"), std::string::npos);
  write_raw(p, R"({"w":{"dtype":"F8_E4M3","shape":[1],"data_offsets":[0,1]}})", "x");
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("unknown dtype"), std::string::npos);
  write_raw(p, R"({"w":{"dtype":"F32","shape":[2],"data_offsets":[0,4]}})", four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("does not match"), std::string::npos);
  write_raw(p, R"({"w":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})", four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("outside the data section"), std::string::npos);
  write_raw(p, R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"b":{"dtype":"F16","shape":[2],"data_offsets":[2,6]}})",
            four + four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("overlap"), std::string::npos);
  write_raw(p, R"({"a":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},"a":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
            four + four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("duplicate tensor name"), std::string::npos);
  write_raw(p, R"({"a":{"dtype":"F32","shape":[1]}})", four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("tensor a"), std::string::npos);
  write_raw(p, R"({"a":{"dtype":"F32","shape":[-1],"data_offsets":[0,4]}})", four);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("bad shape"), std::string::npos);
  EXPECT_NE(error_of([&] { SafeTensorsFile f(d.file("absent.safetensors")); }).find("cannot open"), std::string::npos);
}

// Undefined behaviour found by the fuzzers (caught by the sanitizer build of these tests before the fixes).
TEST(SafeTensors, F16DataAtAnOddOffsetIsReadExactly) {
  TempDir d;
  // A 61-byte header puts the data section at byte 69: every 16-bit value is misaligned.
  std::string header = R"({"h":{"dtype":"F16","shape":[3],"data_offsets":[0,6]}})";
  header.resize(61, ' ');
  ASSERT_NE((8 + header.size()) % 2, 0u);
  write_raw(d.file("odd.safetensors"), header, std::string("\x00\x3c\x00\xc0\x00\x7c", 6));  // 1, -2, inf
  SafeTensorsFile f(d.file("odd.safetensors"));
  const Tensor t = f.find("h")->to_f32();
  EXPECT_EQ(t[0], 1.0f);
  EXPECT_EQ(t[1], -2.0f);
  EXPECT_TRUE(std::isinf(t[2]));
}

TEST(SafeTensors, EmptyTensorsConvertWithoutTouchingData) {
  TempDir d;
  write_raw(d.file("e.safetensors"),
            R"({"f":{"dtype":"F32","shape":[0],"data_offsets":[0,0]},"i":{"dtype":"I64","shape":[2,0],"data_offsets":[0,0]},)"
            R"("h":{"dtype":"BF16","shape":[0,5],"data_offsets":[0,0]}})",
            "");
  SafeTensorsFile f(d.file("e.safetensors"));
  EXPECT_EQ(f.find("f")->to_f32().numel(), 0);
  EXPECT_TRUE(f.find("i")->to_i64().empty());
  EXPECT_EQ(f.find("h")->to_f32().numel(), 0);
}

TEST(SafeTensors, HugeShapesNeverOverflow) {
  TempDir d;
  const std::string p = d.file("huge.safetensors");
  write_raw(p, R"({"z":{"dtype":"F32","shape":[4294967296,4294967296,0],"data_offsets":[0,0]}})", "");
  EXPECT_EQ(SafeTensorsFile(p).find("z")->numel(), 0);  // a zero dimension: empty, however large the others
  write_raw(p, R"({"w":{"dtype":"F32","shape":[4294967296,4294967296,4],"data_offsets":[0,0]}})", "");
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("more elements than can be addressed"), std::string::npos);
  // 2^62 x 4 bytes wraps to 0 in 64 bits: still rejected.
  write_raw(p, R"({"w":{"dtype":"F32","shape":[4611686018427387904],"data_offsets":[0,0]}})", "");
  EXPECT_NE(error_of([&] { SafeTensorsFile f(p); }).find("does not match"), std::string::npos);
}

TEST(SafeTensors, AtomicWriteLeavesNoTemporaryAndReplaces) {
  TempDir d;
  const std::string p = d.file("out.txt");
  write_file_atomic(p, std::string("first"));
  write_file_atomic(p, std::string("second"));
  std::ifstream in(p);
  std::string s;
  in >> s;
  EXPECT_EQ(s, "second");
  int files = 0;
  for (const auto& e : fs::directory_iterator(fs::path(p).parent_path())) files += e.is_regular_file();
  EXPECT_EQ(files, 1);
  {  // an uncommitted writer removes its temporary file and leaves the old content
    AtomicFileWriter w(p);
    w.write("partial", 7);
  }
  std::ifstream in2(p);
  in2 >> s;
  EXPECT_EQ(s, "second");
  EXPECT_THROW(write_file_atomic(d.file("no/such/dir/x"), std::string("x")), Error);
}

TEST(WeightMap, ShapeCheckedLookupAndViews) {
  TempDir d;
  write_safetensors(d.file("model.safetensors"),
                    {to_write("blocks.0.conv.weight", Tensor::full({4, 2, 3, 3}, 0.5f), DType::F16),
                     to_write("blocks.0.conv.bias", Tensor::full({4}, 1.0f)),
                     to_write("extra.position_ids", Tensor::full({3}, 0.0f))});
  WeightMap m = WeightMap::load_dir(d.path_str(), "model", "test");
  const WeightView b = m.root().sub("blocks.0");
  EXPECT_EQ(b.key("conv.weight"), "blocks.0.conv.weight");
  EXPECT_TRUE(b.has("conv.bias"));
  WeightRef w = b.get("conv.weight", {4, 2, 3, 3});
  EXPECT_EQ(w.dtype, DType::F16);
  EXPECT_EQ(b.get_f32("conv.weight", {4, 2, 3, 3})[5], 0.5f);
  const std::string shape_err = error_of([&] { b.get("conv.bias", {5}); });
  EXPECT_NE(shape_err.find("blocks.0.conv.bias"), std::string::npos) << shape_err;
  EXPECT_NE(shape_err.find("[4]"), std::string::npos) << shape_err;
  EXPECT_NE(shape_err.find("[5]"), std::string::npos) << shape_err;
  const std::string missing = error_of([&] { b.get("norm.weight", {4}); });
  EXPECT_NE(missing.find("missing tensor blocks.0.norm.weight"), std::string::npos) << missing;
  b.get("conv.bias", {4});
  EXPECT_EQ(m.unused_keys(), std::vector<std::string>{"extra.position_ids"});
  EXPECT_NO_THROW(m.check_all_used({"position_ids"}));
  EXPECT_NE(error_of([&] { m.check_all_used({}); }).find("unexpected tensor extra.position_ids"), std::string::npos);
}

TEST(WeightMap, ShardedCheckpointAndVariants) {
  TempDir d;
  write_safetensors(d.file("m-00001-of-00002.safetensors"), {to_write("a", Tensor::full({2}, 1.0f))});
  write_safetensors(d.file("m-00002-of-00002.safetensors"), {to_write("b", Tensor::full({3}, 2.0f))});
  nlohmann::json idx = {{"metadata", {{"total_size", 20}}},
                        {"weight_map", {{"a", "m-00001-of-00002.safetensors"}, {"b", "m-00002-of-00002.safetensors"}}}};
  write_file_atomic(d.file("m.safetensors.index.json"), dump_json(idx));
  WeightMap m = WeightMap::load_dir(d.path_str(), "m", "sharded");
  EXPECT_EQ(m.root().get_f32("b", {3})[2], 2.0f);
  EXPECT_EQ(m.keys().size(), 2u);
  // an index naming a tensor its shard lacks
  idx["weight_map"]["c"] = "m-00001-of-00002.safetensors";
  write_file_atomic(d.file("m.safetensors.index.json"), dump_json(idx));
  EXPECT_NE(error_of([&] { WeightMap::load_dir(d.path_str(), "m", "sharded"); }).find("not in the shard"),
            std::string::npos);
  // fp16 variant file
  write_safetensors(d.file("v.fp16.safetensors"), {to_write("x", Tensor::full({1}, 3.0f), DType::F16)});
  EXPECT_EQ(WeightMap::load_dir(d.path_str(), "v", "variant").root().get_f32("x", {1})[0], 3.0f);
  EXPECT_NE(error_of([&] { WeightMap::load_dir(d.path_str(), "none", "comp"); }).find("no none.safetensors"),
            std::string::npos);
}

TEST(WeightMap, UnalignedF32DataIsCopied) {
  TempDir d;
  // one F16 value first, so the F32 tensor starts at data offset 2 (not 4-byte aligned)
  uint16_t h = float_to_half(1.0f);
  float v[2] = {3.5f, -4.0f};
  std::string data(reinterpret_cast<char*>(&h), 2);
  data += std::string(reinterpret_cast<char*>(v), 8);
  std::string header = R"({"h":{"dtype":"F16","shape":[1],"data_offsets":[0,2]},"f":{"dtype":"F32","shape":[2],"data_offsets":[2,10]}})";
  while ((8 + header.size()) % 8) header += ' ';
  write_raw(d.file("u.safetensors"), header, data);
  WeightMap m = WeightMap::load_file(d.file("u.safetensors"), "u");
  WeightRef r = m.root().get("f", {2});
  EXPECT_EQ(reinterpret_cast<uintptr_t>(r.data) % 4, 0u);
  EXPECT_EQ(static_cast<const float*>(r.data)[1], -4.0f);
}

TEST(WeightMap, RecorderEnumeratesRequests) {
  WeightMap rec = WeightMap::recorder("r");
  const WeightView v = rec.root().sub("x");
  WeightRef r = v.get("w", {3, 4});
  EXPECT_EQ(r.data, nullptr);
  EXPECT_EQ(v.get_f32("b", {3})[2], 0.0f);
  ASSERT_EQ(rec.recorded().size(), 2u);
  EXPECT_EQ(rec.recorded()[0].first, "x.w");
  EXPECT_EQ(rec.recorded()[0].second, (Shape{3, 4}));
}

// Found by fuzz_configs: an integer field holding a float too large for int64 was cast (undefined behaviour).
TEST(Config, IntegerFieldsHoldingHugeOrFractionalNumbersAreErrors) {
  const Config c(parse_json(R"({"a": 16.0, "b": 1.1e102, "c": 2.5, "d": -1e300})"), "x.json");
  EXPECT_EQ(c.get_int("a"), 16);
  for (const char* k : {"b", "c", "d"})
    EXPECT_NE(error_of([&] { c.get_int(k); }).find("x.json: field '" + std::string(k) + "': expected an integer"),
              std::string::npos)
        << k;
}

TEST(Config, ListsOrScalarsPerBlockAndErrors) {
  Config c(parse_json(R"({"heads": 8, "chans": [32, 64], "f": 0.5, "name": "x", "flag": true,
                                      "nested": {"k": 3}, "bad": "s"})"),
           "cfg.json");
  EXPECT_EQ(c.get_int_per_block("heads", 3), (std::vector<int64_t>{8, 8, 8}));
  EXPECT_EQ(c.get_int_per_block("chans", 2), (std::vector<int64_t>{32, 64}));
  EXPECT_DOUBLE_EQ(c.get_double("f"), 0.5);
  EXPECT_EQ(c.get_int("missing", 7), 7);
  EXPECT_TRUE(c.get_bool("flag", false));
  EXPECT_EQ(c.sub("nested").get_int("k"), 3);
  const std::string e1 = error_of([&] { c.get_int_per_block("chans", 3); });
  EXPECT_NE(e1.find("cfg.json: field 'chans'"), std::string::npos) << e1;
  EXPECT_NE(error_of([&] { c.get_int("bad"); }).find("expected an integer"), std::string::npos);
  EXPECT_NE(error_of([&] { c.get_int("absent"); }).find("missing"), std::string::npos);
}

TEST(JsonText, ParsesAndWritesBothObjectKinds) {
  std::istringstream in(R"({"b": [1, 2.5, "x"], "a": {"t": true}})");
  const nlohmann::json j = parse_json(in);
  EXPECT_EQ(dump_json(j), R"({"a":{"t":true},"b":[1,2.5,"x"]})");  // keys sorted
  EXPECT_EQ(dump_json(j["a"], 2), "{\n  \"t\": true\n}");
  nlohmann::ordered_json o;
  o["z"] = 1;
  o["a"] = nullptr;
  EXPECT_EQ(dump_json(o), R"({"z":1,"a":null})");  // insertion order
  EXPECT_THROW(parse_json(std::string_view(R"({"a": )")), nlohmann::json::parse_error);
  // The callback sees every key; text outside the view is not read.
  const std::string text = R"({"k": 1, "k": 2}trailing)";
  int keys = 0;
  const nlohmann::json::parser_callback_t count = [&](int depth, nlohmann::json::parse_event_t event,
                                                     nlohmann::json&) {
    keys += depth == 1 && event == nlohmann::json::parse_event_t::key;
    return true;
  };
  EXPECT_EQ(parse_json(std::string_view(text).substr(0, text.size() - 8), count)["k"].get<int>(), 2);
  EXPECT_EQ(keys, 2);
}

TEST(JsonText, InvalidUtf8IsAnErrorUnlessReplaced) {
  const nlohmann::json j = std::string("a\xff");
  EXPECT_THROW(dump_json(j), nlohmann::json::type_error);
  EXPECT_EQ(dump_json(j, -1, true), "\"a\xEF\xBF\xBD\"");
}

}  // namespace
}  // namespace egopd
