// Sharded / single-file weight writing, stale-layout cleanup, and bad input files (truncated, duplicate names,
// unknown dtype) giving one-line errors that name the problem.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "convert/dtype_convert.h"
#include "convert/inspect.h"
#include "convert/tensor_io.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "pipeline/synthetic_model.h"
#include "test_util.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;
using test::ScratchDir;

// Tensors whose bytes are a simple function of (tensor, index), so any mix-up shows.
std::vector<OutTensor> sample_tensors() {
  std::vector<OutTensor> t;
  const std::vector<std::pair<std::string, std::vector<int64_t>>> specs = {
      {"a.weight", {4, 8}}, {"a.bias", {4}}, {"b.weight", {16, 3}}, {"c", {}}, {"d.weight", {2, 2, 3, 3}}};
  int tag = 0;
  for (const auto& [name, shape] : specs) {
    ++tag;
    t.push_back({name, DType::F32, shape, [tag, shape = shape](uint8_t* dst) {
                   int64_t n = 1;
                   for (int64_t d : shape) n *= d;
                   for (int64_t i = 0; i < n; ++i) {
                     const float v = float(tag * 1000 + i);
                     std::memcpy(dst + 4 * i, &v, 4);
                   }
                 }});
  }
  t.push_back({"ids", DType::I64, {3}, [](uint8_t* dst) {
                 const int64_t v[3] = {7, 8, 9};
                 std::memcpy(dst, v, 24);
               }});
  return t;
}

void expect_matches(const WeightMap& w, const std::vector<OutTensor>& tensors) {
  ASSERT_EQ(w.keys().size(), tensors.size());
  for (const auto& t : tensors) {
    const StoredTensor* s = w.find(t.name);
    ASSERT_NE(s, nullptr) << t.name;
    EXPECT_EQ(s->dtype, t.dtype) << t.name;
    EXPECT_EQ(s->shape, t.shape) << t.name;
    std::vector<uint8_t> want(t.nbytes());
    t.fill(want.data());
    ASSERT_EQ(s->nbytes, want.size()) << t.name;
    EXPECT_EQ(std::memcmp(s->data, want.data(), want.size()), 0) << t.name;
  }
}

TEST(WriteWeights, ShardedWriteLoadsTheSameTensorsAndReplacesStaleLayouts) {
  ScratchDir dir("shards");
  const auto tensors = sample_tensors();
  WriteOptions single;
  write_weights(dir.str(), "model", tensors, single);
  expect_matches(WeightMap::load_dir(dir.str(), "model", "t"), tensors);

  WriteOptions sharded;
  // Greedy in order with a 150-byte limit: [a.weight 128 + a.bias 16] [b.weight 192] [c 4 + d.weight 144] [ids 24].
  sharded.shard_bytes = 150;
  const auto files = write_weights(dir.str(), "model", tensors, sharded);
  ASSERT_EQ(files.size(), 5u);
  EXPECT_EQ(files.front(), "model-00001-of-00004.safetensors");
  EXPECT_EQ(files.back(), "model.safetensors.index.json");
  EXPECT_FALSE(fs::exists(dir.path / "model.safetensors")) << "the stale single file would shadow the index";
  std::ifstream in(dir.path / "model.safetensors.index.json");
  const nlohmann::json index = parse_json(in);
  uint64_t total = 0;
  for (const auto& t : tensors) total += t.nbytes();
  EXPECT_EQ(index["metadata"]["total_size"].get<uint64_t>(), total);
  EXPECT_EQ(index["weight_map"]["a.bias"].get<std::string>(), "model-00001-of-00004.safetensors");
  EXPECT_EQ(index["weight_map"]["d.weight"].get<std::string>(), "model-00003-of-00004.safetensors");
  expect_matches(WeightMap::load_dir(dir.str(), "model", "t"), tensors);

  write_weights(dir.str(), "model", tensors, single);  // back to one file: index and shards go
  for (size_t i = 0; i + 1 < files.size(); ++i) EXPECT_FALSE(fs::exists(dir.path / files[i])) << files[i];
  EXPECT_FALSE(fs::exists(dir.path / "model.safetensors.index.json"));
  expect_matches(WeightMap::load_dir(dir.str(), "model", "t"), tensors);
}

TEST(WriteWeights, ShardedModelDirectoryPassesInspect) {
  ScratchDir dir("sharded-model");
  write_synthetic_model(dir.str("m"), "tiny", 3, DType::F32, 0);
  WriteOptions w;
  w.shard_bytes = shard_bytes_from_mb(1);
  convert_dtype(dir.str("m"), dir.str("f16"), TargetDType::F16, w);
  const fs::path unet = dir.path / "f16" / "unet";
  EXPECT_FALSE(fs::exists(unet / "diffusion_pytorch_model.safetensors"));
  const auto shards = resolve_weight_files(unet.string(), "diffusion_pytorch_model");
  EXPECT_GT(shards.size(), 1u);  // the tiny U-Net is several MB
  for (const auto& s : shards) {  // the limit counts tensor bytes (as Hugging Face's max_shard_size does)
    uint64_t bytes = 0;
    const SafeTensorsFile file(s);  // named: the range-for must not iterate a destroyed temporary's tensors
    for (const auto& t : file.tensors()) bytes += t.nbytes;
    EXPECT_LE(bytes, uint64_t(1) << 20) << s;
  }
  std::ostringstream report;
  EXPECT_EQ(inspect_path(dir.str("f16"), report, InspectOptions{false}), 0u) << report.str();
  const size_t n = WeightMap::load_dir(dir.str("m/unet"), "diffusion_pytorch_model", "unet").keys().size();
  EXPECT_NE(report.str().find("F16 x" + std::to_string(n) + ")"), std::string::npos) << report.str();
}

// ------------------------------------------------------------------------------------------ bad input

void write_raw(const fs::path& p, const std::string& header, size_t data_bytes) {
  std::ofstream out(p, std::ios::binary);
  const uint64_t n = header.size();
  for (int i = 0; i < 8; ++i) out.put(char(n >> (8 * i)));
  out << header << std::string(data_bytes, '\0');
}

TEST(BadInput, TruncatedFileNamesTheFileAndTheTensor) {
  ScratchDir dir("truncated");
  const fs::path p = dir.path / "w.safetensors";
  write_weights(dir.str(), "w", sample_tensors(), WriteOptions{});
  fs::resize_file(p, fs::file_size(p) - 10);
  test::expect_error([&] { open_weights_file(p.string(), "t"); }, {p.string(), "outside the data section"});
  fs::resize_file(p, 12);  // inside the length prefix's claimed header
  test::expect_error([&] { open_weights_file(p.string(), "t"); }, {p.string(), "exceeds the file size"});
}

TEST(BadInput, DuplicateTensorNamesAreRejected) {
  ScratchDir dir("duplicate");
  const fs::path p = dir.path / "dup.safetensors";
  write_raw(p,
            R"({"x.weight":{"dtype":"F32","shape":[1],"data_offsets":[0,4]},)"
            R"("x.weight":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
            8);
  test::expect_error([&] { open_weights_file(p.string(), "t"); }, {p.string(), "x.weight", "listed twice"});
  // The model directory path goes through the same check.
  fs::create_directories(dir.path / "unet");
  fs::rename(p, dir.path / "unet" / "diffusion_pytorch_model.safetensors");
  test::expect_error([&] { open_weights_dir(dir.str("unet"), "diffusion_pytorch_model", "unet"); },
                     {"x.weight", "listed twice"});
}

TEST(BadInput, UnknownDtypeIsNamed) {
  ScratchDir dir("dtype");
  const fs::path p = dir.path / "f8.safetensors";
  write_raw(p, R"({"w":{"dtype":"F8_E4M3","shape":[4],"data_offsets":[0,4]}})", 4);
  test::expect_error([&] { open_weights_file(p.string(), "t"); }, {p.string(), "tensor w", "unknown dtype", "F8_E4M3"});
  test::expect_error([] { parse_target_dtype("f12"); }, {"unknown target dtype", "f12"});
}

TEST(BadInput, InspectReportsWrongShapesAndMissingTensors) {
  ScratchDir dir("inspect-bad");
  write_synthetic_model(dir.str("m"), "tiny", 5, DType::F32, 0);
  // Rewrite the mask encoder with conv_out.bias mis-shaped and blocks.0.bias missing.
  const fs::path me = dir.path / "m" / "mask_encoder";
  const WeightMap w = WeightMap::load_dir(me.string(), "diffusion_pytorch_model", "mask_encoder");
  std::vector<TensorToWrite> out;
  for (const auto& k : w.keys()) {
    if (k == "blocks.0.bias") continue;
    Tensor t = w.find(k)->to_f32();
    if (k == "conv_out.bias") t = Tensor::zeros(Shape{9});
    out.push_back(to_write(k, t.reshaped(k == "conv_out.bias" ? Shape{9} : Shape(w.find(k)->shape))));
  }
  write_safetensors((me / "diffusion_pytorch_model.safetensors").string(), out);
  std::ostringstream report;
  EXPECT_EQ(inspect_path(dir.str("m"), report, InspectOptions{false}), 2u) << report.str();
  EXPECT_NE(report.str().find("missing blocks.0.bias [8]"), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("shape conv_out.bias has [9], expected [8]"), std::string::npos) << report.str();
}

}  // namespace
}  // namespace egopd
