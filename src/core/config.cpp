#include "core/config.h"

#include <cmath>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/json_text.h"

namespace egopd {

Config::Config() : j_(std::make_shared<const nlohmann::json>(nlohmann::json::object())) {}

Config::Config(nlohmann::json j, std::string source)
    : j_(std::make_shared<const nlohmann::json>(std::move(j))), source_(std::move(source)) {}

bool Config::has(const std::string& key) const {
  return j_->is_object() && j_->contains(key) && !(*j_)[key].is_null();
}

Config Config::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open");
  nlohmann::json j;
  try {
    j = parse_json(in);
  } catch (const std::exception& e) {
    throw Error(path + ": not valid JSON");
  }
  if (!j.is_object()) throw Error(path + ": expected a JSON object");
  return Config(std::move(j), path);
}

void Config::fail(const std::string& key, const std::string& why) const {
  throw Error(source_ + ": field '" + key + "': " + why);
}

const nlohmann::json& Config::at(const std::string& key) const {
  if (!has(key)) fail(key, "missing");
  return (*j_)[key];
}

int64_t Config::get_int(const std::string& key) const {
  const auto& v = at(key);
  if (v.is_number_integer()) return v.get<int64_t>();
  if (v.is_number_float()) {  // 16.0 is an integer; 1e102 or 2.5 is not (and casting them would be undefined)
    const double x = v.get<double>();
    if (std::isfinite(x) && x == std::floor(x) && x >= -9.2e18 && x <= 9.2e18) return int64_t(x);
  }
  fail(key, "expected an integer, got " + dump_json(v));
}

int64_t Config::get_int(const std::string& key, int64_t fallback) const { return has(key) ? get_int(key) : fallback; }

double Config::get_double(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_number()) fail(key, "expected a number, got " + dump_json(v));
  const double x = v.get<double>();
  if (!std::isfinite(x)) fail(key, "not a finite number");
  return x;
}

double Config::get_double(const std::string& key, double fallback) const {
  return has(key) ? get_double(key) : fallback;
}

bool Config::get_bool(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  const auto& v = (*j_)[key];
  if (!v.is_boolean()) fail(key, "expected true or false, got " + dump_json(v));
  return v.get<bool>();
}

std::string Config::get_string(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_string()) fail(key, "expected a string, got " + dump_json(v));
  return v.get<std::string>();
}

std::string Config::get_string(const std::string& key, const std::string& fallback) const {
  return has(key) ? get_string(key) : fallback;
}

std::vector<std::string> Config::get_string_list(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_array()) fail(key, "expected a list of strings");
  std::vector<std::string> out;
  for (const auto& e : v) {
    if (!e.is_string()) fail(key, "expected a list of strings, found " + dump_json(e));
    out.push_back(e.get<std::string>());
  }
  return out;
}

std::vector<double> Config::get_double_list(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_array()) fail(key, "expected a list of numbers");
  std::vector<double> out;
  for (const auto& e : v) {
    if (!e.is_number()) fail(key, "expected a list of numbers, found " + dump_json(e));
    out.push_back(e.get<double>());
  }
  return out;
}

std::vector<int64_t> Config::get_int_list(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_array()) fail(key, "expected a list of integers");
  std::vector<int64_t> out;
  for (const auto& e : v) {
    if (!e.is_number_integer()) fail(key, "expected a list of integers, found " + dump_json(e));
    out.push_back(e.get<int64_t>());
  }
  return out;
}

std::vector<int64_t> Config::get_int_per_block(const std::string& key, size_t n) const {
  const auto& v = at(key);
  if (v.is_number_integer()) return std::vector<int64_t>(n, v.get<int64_t>());
  std::vector<int64_t> out = get_int_list(key);
  if (out.size() != n) fail(key, "expected " + std::to_string(n) + " values (one per block), got " + std::to_string(out.size()));
  return out;
}

namespace {
std::string num(double v) {
  std::ostringstream o;
  o << v;
  return o.str();
}
}  // namespace

int64_t Config::get_int(const std::string& key, IntRange r) const {
  const int64_t v = get_int(key);
  if (v < r.lo || v > r.hi)
    fail(key, "must be between " + std::to_string(r.lo) + " and " + std::to_string(r.hi) + ", got " + std::to_string(v));
  return v;
}

int64_t Config::get_int(const std::string& key, int64_t fallback, IntRange r) const {
  return has(key) ? get_int(key, r) : fallback;
}

double Config::get_double(const std::string& key, RealRange r) const {
  const double v = get_double(key);
  if (v > r.hi || (r.lo_open ? v <= r.lo : v < r.lo))
    fail(key, std::string("must be ") + (r.lo_open ? "> " : ">= ") + num(r.lo) + " and <= " + num(r.hi) + ", got " +
                  num(v));
  return v;
}

double Config::get_double(const std::string& key, double fallback, RealRange r) const {
  return has(key) ? get_double(key, r) : fallback;
}

std::vector<int64_t> Config::get_int_list(const std::string& key, IntRange r) const {
  std::vector<int64_t> out = get_int_list(key);
  if (out.empty()) fail(key, "must not be empty");
  for (int64_t v : out)
    if (v < r.lo || v > r.hi)
      fail(key, "values must be between " + std::to_string(r.lo) + " and " + std::to_string(r.hi) + ", got " +
                    std::to_string(v));
  return out;
}

std::vector<int64_t> Config::get_int_per_block(const std::string& key, size_t n, IntRange r) const {
  std::vector<int64_t> out = get_int_per_block(key, n);
  for (int64_t v : out)
    if (v < r.lo || v > r.hi)
      fail(key, "values must be between " + std::to_string(r.lo) + " and " + std::to_string(r.hi) + ", got " +
                    std::to_string(v));
  return out;
}

Config Config::sub(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_object()) fail(key, "expected an object");
  return Config(v, source_ + ":" + key);
}

}  // namespace egopd
