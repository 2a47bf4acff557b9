#pragma once
// Helpers shared by the converter tests: scratch directories and tensor-for-tensor comparison of weight maps.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <string>

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
