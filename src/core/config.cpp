#include "core/config.h"

#include <fstream>

#include "core/error.h"

namespace egopd {

Config Config::load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot open");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
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
  return j_[key];
}

int64_t Config::get_int(const std::string& key) const {
  const auto& v = at(key);
  if (v.is_number_integer()) return v.get<int64_t>();
  if (v.is_number_float() && v.get<double>() == double(int64_t(v.get<double>()))) return int64_t(v.get<double>());
  fail(key, "expected an integer, got " + v.dump());
}

int64_t Config::get_int(const std::string& key, int64_t fallback) const { return has(key) ? get_int(key) : fallback; }

double Config::get_double(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_number()) fail(key, "expected a number, got " + v.dump());
  return v.get<double>();
}

double Config::get_double(const std::string& key, double fallback) const {
  return has(key) ? get_double(key) : fallback;
}

bool Config::get_bool(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  const auto& v = j_[key];
  if (!v.is_boolean()) fail(key, "expected true or false, got " + v.dump());
  return v.get<bool>();
}

std::string Config::get_string(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_string()) fail(key, "expected a string, got " + v.dump());
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
    if (!e.is_string()) fail(key, "expected a list of strings, found " + e.dump());
    out.push_back(e.get<std::string>());
  }
  return out;
}

std::vector<double> Config::get_double_list(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_array()) fail(key, "expected a list of numbers");
  std::vector<double> out;
  for (const auto& e : v) {
    if (!e.is_number()) fail(key, "expected a list of numbers, found " + e.dump());
    out.push_back(e.get<double>());
  }
  return out;
}

std::vector<int64_t> Config::get_int_list(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_array()) fail(key, "expected a list of integers");
  std::vector<int64_t> out;
  for (const auto& e : v) {
    if (!e.is_number_integer()) fail(key, "expected a list of integers, found " + e.dump());
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

Config Config::sub(const std::string& key) const {
  const auto& v = at(key);
  if (!v.is_object()) fail(key, "expected an object");
  return Config(v, source_ + ":" + key);
}

}  // namespace egopd
