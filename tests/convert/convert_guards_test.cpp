// Broken weights are found, never carried along: `inspect` lists every tensor holding NaN/Inf and a weight of a
// type the runtime cannot use; `dtype` refuses values that overflow the target type and NaN/Inf (q8 would write
// zeros with scale 0); a conversion that fails leaves no output folder and an earlier one untouched.
#include <gtest/gtest.h>

#include <filesystem>
#include <limits>
#include <sstream>

#include "convert/dtype_convert.h"
#include "convert/inspect.h"
#include "convert/tensor_io.h"
#include "convert/test_util.h"
#include "core/error.h"
#include "pipeline/synthetic_model.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;
using test::ScratchDir;

const float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string inspect_report(const std::string& path, size_t* problems) {
  std::ostringstream out;
  *problems = inspect_path(path, out, InspectOptions{false});
  return out.str();
}

TEST(ConvertGuards, InspectFindsEveryNonFiniteTensor) {
  ScratchDir d("inspect-nan");
  write_synthetic_model(d.str("m"), "tiny", 5, DType::F32, 0);
  size_t problems = 0;
  inspect_report(d.str("m"), &problems);
  ASSERT_EQ(problems, 0u);
  test::set_stored_f32(d.path / "m/unet/diffusion_pytorch_model.safetensors", "conv_out.bias", 0, kNaN);
  test::set_stored_f32(d.path / "m/unet/diffusion_pytorch_model.safetensors", "conv_out.bias", 2, kNaN);
  test::set_stored_f32(d.path / "m/vae/diffusion_pytorch_model.safetensors", "decoder.conv_out.bias", 1,
                       std::numeric_limits<float>::infinity());
  const std::string r = inspect_report(d.str("m"), &problems);
  EXPECT_EQ(problems, 2u) << r;
  EXPECT_NE(r.find("problem: non-finite conv_out.bias: 2 of 4 values are NaN or Inf"), std::string::npos) << r;
  EXPECT_NE(r.find("problem: non-finite decoder.conv_out.bias: 1 of 3 values are NaN or Inf"), std::string::npos)
      << r;
  // A single weight file too.
  inspect_report((d.path / "m/unet/diffusion_pytorch_model.safetensors").string(), &problems);
  EXPECT_EQ(problems, 1u);
}

TEST(ConvertGuards, InspectReportsAnIntegerWeight) {
  ScratchDir d("inspect-int");
  write_synthetic_model(d.str("m"), "tiny", 5, DType::F32, 0);
  // Rewrite the mask encoder with one weight stored as I32 (same shape and byte size).
  const std::string file = d.str("m/mask_encoder/diffusion_pytorch_model.safetensors");
  const WeightMap w = WeightMap::load_dir(d.str("m/mask_encoder"), "diffusion_pytorch_model", "mask_encoder");
  std::vector<OutTensor> tensors;
  for (const auto& k : w.keys()) {
    const StoredTensor* t = w.find(k);
    const DType dt = k == "conv_out.weight" ? DType::I32 : t->dtype;
    tensors.push_back({k, dt, t->shape, [t](uint8_t* dst) { std::memcpy(dst, t->data, t->nbytes); }});
  }
  ScratchDir out("inspect-int-out");
  write_weights(out.str(), "diffusion_pytorch_model", tensors, WriteOptions{});
  fs::copy_file(out.path / "diffusion_pytorch_model.safetensors", file, fs::copy_options::overwrite_existing);
  size_t problems = 0;
  const std::string r = inspect_report(d.str("m"), &problems);
  EXPECT_GE(problems, 1u) << r;
  EXPECT_NE(r.find("dtype conv_out.weight is I32"), std::string::npos) << r;
}

class DTypeGuards : public ::testing::Test {
 protected:
  ScratchDir d{"dtype-guards"};
  void SetUp() override { write_synthetic_model(d.str("m"), "tiny", 5, DType::F32, 0); }
  // Converts the model folder as `egopd-convert dtype` does (written whole).
  void convert(const std::string& out, TargetDType to) {
    write_model_folder(out, "model_index.json",
                       [&](const std::string& dir) { convert_dtype(d.str("m"), dir, to, WriteOptions{}); });
  }
};

TEST_F(DTypeGuards, OverflowToHalfIsRefusedAndLeavesNoFolder) {
  test::set_stored_f32(d.path / "m/unet/diffusion_pytorch_model.safetensors", "conv_out.bias", 1, 3e38f);
  test::expect_error([&] { convert(d.str("f16"), TargetDType::F16); },
                     {"conv_out.bias", "overflows F16", "65504"});
  EXPECT_FALSE(fs::exists(d.path / "f16"));
  for (const auto& e : fs::directory_iterator(d.path))  // no temporary folder either
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos) << e.path();
  // bf16 holds 3e38: that conversion is fine.
  EXPECT_NO_THROW(convert(d.str("bf16"), TargetDType::BF16));
}

TEST_F(DTypeGuards, NaNIsRefusedByQ8AndAnEarlierOutputIsKept) {
  convert(d.str("q8"), TargetDType::Q8);  // a good earlier conversion
  const std::string before = test::read_file(d.str("q8/unet/diffusion_pytorch_model.safetensors"));
  test::set_stored_f32(d.path / "m/unet/diffusion_pytorch_model.safetensors", "conv_in.weight", 7, kNaN);
  test::expect_error([&] { convert(d.str("q8"), TargetDType::Q8); }, {"conv_in.weight", "NaN/Inf"});
  EXPECT_EQ(test::read_file(d.str("q8/unet/diffusion_pytorch_model.safetensors")), before);
}

TEST_F(DTypeGuards, AnUnrelatedFolderIsNeverReplaced) {
  fs::create_directories(d.path / "notes");
  std::ofstream(d.path / "notes" / "todo.txt") << "keep me";
  test::expect_error([&] { convert(d.str("notes"), TargetDType::F16); }, {"is not an earlier output"});
  EXPECT_TRUE(fs::exists(d.path / "notes" / "todo.txt"));
}

}  // namespace
}  // namespace egopd
