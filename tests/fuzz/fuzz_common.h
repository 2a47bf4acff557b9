#pragma once
// Shared by the libFuzzer targets: the input as a string or as a scratch file (the readers under test take paths),
// and the one rule every target checks: a malformed input may only end in egopd::Error (a one-line message);
// any other exception is a finding (abort, so libFuzzer keeps the reproducer), as are crashes and sanitizer
// reports.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/error.h"

namespace egopd::fuzz {

inline std::string as_string(const uint8_t* data, size_t size) { return std::string(reinterpret_cast<const char*>(data), size); }

// A per-process scratch folder (libFuzzer may run several processes).
inline const std::filesystem::path& scratch() {
  static const std::filesystem::path dir = [] {
    const auto d = std::filesystem::temp_directory_path() / ("egopd-fuzz-" + std::to_string(::getpid()));
    std::filesystem::create_directories(d);
    return d;
  }();
  return dir;
}

inline std::string write_scratch(const std::string& name, const std::string& bytes) {
  const auto p = scratch() / name;
  std::filesystem::create_directories(p.parent_path());
  std::ofstream(p, std::ios::binary | std::ios::trunc) << bytes;
  return p.string();
}

template <class F>
void expect_only_egopd_errors(F&& f) {
  try {
    f();
  } catch (const Error&) {
    // the one allowed outcome for malformed input
  } catch (const std::exception& e) {
    std::fprintf(stderr, "finding: exception other than egopd::Error: %s\n", e.what());
    std::abort();
  }
}

// Splits the input at the first "\n----\n" into two parts (for targets that need two files).
inline std::pair<std::string, std::string> split2(const std::string& s) {
  const size_t at = s.find("\n----\n");
  if (at == std::string::npos) return {s, ""};
  return {s.substr(0, at), s.substr(at + 6)};
}

}  // namespace egopd::fuzz
