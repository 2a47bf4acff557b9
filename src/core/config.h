#pragma once
// config.json access with field-naming errors ("unet/config.json: field 'block_out_channels': ...").
// diffusers / transformers configs give per-block values either as a list or as one scalar for every block.
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

namespace egopd {

// Bounds of a config value; a read outside them is an error naming the file, field, bounds and value.
struct IntRange {
  int64_t lo, hi;
};
struct RealRange {
  double lo, hi;
  bool lo_open = false;  // lo < v instead of lo <= v (eps, sigmas: strictly positive)
};
// Common bounds: a channel / width count, a per-block repeat count.
constexpr IntRange kChannelRange{1, 1 << 16};
constexpr IntRange kCountRange{1, 1024};
// Normalisation eps: positive and small; noise levels of the samplers: positive and below the point where their
// squares overflow single precision; classifier-free guidance scales.
constexpr RealRange kEpsRange{0, 1, true};
constexpr RealRange kSigmaRange{0, 1e6, true};
constexpr RealRange kGuidanceRange{0, 100};

class Config {
 public:
  Config();  // an empty object
  Config(nlohmann::json j, std::string source);
  static Config load(const std::string& path);

  bool has(const std::string& key) const;
  int64_t get_int(const std::string& key) const;
  int64_t get_int(const std::string& key, int64_t fallback) const;
  double get_double(const std::string& key) const;
  double get_double(const std::string& key, double fallback) const;
  bool get_bool(const std::string& key, bool fallback) const;
  std::string get_string(const std::string& key) const;
  std::string get_string(const std::string& key, const std::string& fallback) const;
  std::vector<std::string> get_string_list(const std::string& key) const;
  std::vector<double> get_double_list(const std::string& key) const;
  // A list of exactly n ints, or one int repeated n times.
  std::vector<int64_t> get_int_per_block(const std::string& key, size_t n) const;
  std::vector<int64_t> get_int_list(const std::string& key) const;
  // Ranged reads (non-finite numbers are always rejected, ranged or not).
  int64_t get_int(const std::string& key, IntRange r) const;
  int64_t get_int(const std::string& key, int64_t fallback, IntRange r) const;
  double get_double(const std::string& key, RealRange r) const;
  double get_double(const std::string& key, double fallback, RealRange r) const;
  std::vector<int64_t> get_int_list(const std::string& key, IntRange r) const;
  std::vector<int64_t> get_int_per_block(const std::string& key, size_t n, IntRange r) const;
  Config sub(const std::string& key) const;  // nested object (error if missing)

  const nlohmann::json& json() const { return *j_; }
  const std::string& source() const { return source_; }
  [[noreturn]] void fail(const std::string& key, const std::string& why) const;

 private:
  const nlohmann::json& at(const std::string& key) const;
  // Never null. Shared between copies (a Config is read-only), and behind a pointer so that this header needs only
  // json_fwd.hpp (the full JSON header takes about 3 s to parse where no precompiled header holds it).
  std::shared_ptr<const nlohmann::json> j_;
  std::string source_;
};

}  // namespace egopd
