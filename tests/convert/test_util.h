#pragma once
// Helpers shared by the converter tests: scratch directories and tensor-for-tensor comparison of weight maps.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"
#include "core/json_text.h"
#include "core/weights.h"

namespace egopd::test {

// A fresh directory under the system temp dir, removed with its contents at scope exit.
struct ScratchDir {
  std::filesystem::path path;
  explicit ScratchDir(const std::string& tag) {
    static int counter = 0;
    path = std::filesystem::temp_directory_path() /
           ("egopd-convert-test-" + tag + "-" + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  std::string str(const std::string& sub = "") const { return sub.empty() ? path.string() : (path / sub).string(); }
};

// Sets element `index` of the F32 tensor `tensor` of a safetensors file in place (a corrupt download in one value).
inline void set_stored_f32(const std::filesystem::path& file, const std::string& tensor, int64_t index, float value) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  uint64_t header_len = 0;
  f.read(reinterpret_cast<char*>(&header_len), 8);
  std::string header(header_len, '\0');
  f.read(header.data(), std::streamsize(header_len));
  const nlohmann::json h = parse_json(header);
  ASSERT_TRUE(h.contains(tensor)) << tensor;
  ASSERT_EQ(h[tensor]["dtype"].get<std::string>(), "F32");
  const uint64_t begin = h[tensor]["data_offsets"][0].get<uint64_t>();
  f.seekp(std::streamoff(8 + header_len + begin + uint64_t(index) * 4));
  f.write(reinterpret_cast<const char*>(&value), 4);
  ASSERT_TRUE(f.good()) << file;
}

// Same key set, and for every key the same dtype, shape and bytes.
inline void expect_same_tensors(const WeightMap& a, const WeightMap& b, const std::string& what) {
  ASSERT_EQ(a.keys(), b.keys()) << what;
  for (const auto& k : a.keys()) {
    const StoredTensor* x = a.find(k);
    const StoredTensor* y = b.find(k);
    ASSERT_EQ(x->dtype, y->dtype) << what << ": " << k;
    ASSERT_EQ(x->shape, y->shape) << what << ": " << k;
    ASSERT_EQ(x->nbytes, y->nbytes) << what << ": " << k;
    EXPECT_EQ(std::memcmp(x->data, y->data, x->nbytes), 0) << what << ": " << k << " differs";
  }
}

inline std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// Runs f, expecting an egopd::Error whose one-line message contains every needle.
template <typename F>
void expect_error(F&& f, const std::vector<std::string>& needles) {
  try {
    f();
    ADD_FAILURE() << "no error thrown";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.find('\n'), std::string::npos) << "not one line: " << msg;
    for (const auto& n : needles) EXPECT_NE(msg.find(n), std::string::npos) << "'" << n << "' not in: " << msg;
  }
}

}  // namespace egopd::test
