#include "cli/args.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <nlohmann/json.hpp>
#include <new>

#include "core/error.h"
#include "core/interrupt.h"

namespace egopd {

Args::Args(std::string command, const std::vector<std::string>& argv) : command_(std::move(command)) {
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& a = argv[i];
    if (a.rfind("--", 0) == 0 && a.size() > 2) {
      std::string name = a.substr(2);
      auto eq = name.find('=');
      if (eq != std::string::npos) {
        values_[name.substr(0, eq)] = name.substr(eq + 1);
      } else if (i + 1 < argv.size() && (argv[i + 1].rfind("--", 0) != 0 || argv[i + 1].size() == 2)) {
        values_[name] = argv[++i];
      } else {
        flags_.insert(name);
      }
    } else {
      positional_.push_back(a);
    }
  }
}

bool Args::has(const std::string& name) const {
  read_.insert(name);
  return values_.count(name) || flags_.count(name);
}

std::string Args::get(const std::string& name, const std::string& fallback) const {
  read_.insert(name);
  auto it = values_.find(name);
  if (it != values_.end()) return it->second;
  if (flags_.count(name)) throw Error(command_ + ": option --" + name + " needs a value");
  return fallback;
}

std::string Args::require(const std::string& name) const {
  read_.insert(name);
  auto it = values_.find(name);
  if (it == values_.end()) throw Error(command_ + ": option --" + name + " is required");
  return it->second;
}

namespace {
bool all_digits(const std::string& s, size_t from) {
  if (s.size() <= from) return false;
  for (size_t i = from; i < s.size(); ++i)
    if (s[i] < '0' || s[i] > '9') return false;
  return true;
}
}  // namespace

int64_t Args::get_int(const std::string& name, int64_t fallback, int64_t lo, int64_t hi) const {
  if (!has(name)) return fallback;
  const std::string v = get(name, "");
  const std::string bounds = lo == INT64_MIN ? "" : " (" + std::to_string(lo) + ".." + std::to_string(hi) + ")";
  if (!all_digits(v, v.size() && v[0] == '-' ? 1 : 0))
    throw Error(command_ + ": --" + name + " expects an integer" + bounds + ", got '" + v + "'");
  errno = 0;
  const long long x = std::strtoll(v.c_str(), nullptr, 10);
  if (errno == ERANGE || x < lo || x > hi)
    throw Error(command_ + ": --" + name + " must be between " + std::to_string(lo) + " and " + std::to_string(hi) +
                ", got " + v);
  return x;
}

uint64_t Args::get_uint64(const std::string& name, uint64_t fallback) const {
  if (!has(name)) return fallback;
  const std::string v = get(name, "");
  if (!all_digits(v, 0))
    throw Error(command_ + ": --" + name + " expects an integer from 0 to 18446744073709551615, got '" + v + "'");
  errno = 0;
  const unsigned long long x = std::strtoull(v.c_str(), nullptr, 10);
  if (errno == ERANGE)
    throw Error(command_ + ": --" + name + " must be between 0 and 18446744073709551615, got " + v);
  return x;
}

double Args::get_double(const std::string& name, double fallback) const {
  if (!has(name)) return fallback;
  const std::string v = get(name, "");
  char* end = nullptr;
  errno = 0;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || *end != '\0' || std::isspace(static_cast<unsigned char>(v[0])))
    throw Error(command_ + ": --" + name + " expects a number, got '" + v + "'");
  if (!std::isfinite(x) || errno == ERANGE) throw Error(command_ + ": --" + name + " is out of range: " + v);
  return x;
}

bool Args::flag(const std::string& name) const {
  read_.insert(name);
  if (values_.count(name)) {
    const std::string& v = values_.at(name);
    if (v == "1" || v == "true") return true;
    if (v == "0" || v == "false") return false;
    throw Error(command_ + ": option --" + name + " takes no value (got '" + v + "')");
  }
  return flags_.count(name) != 0;
}

void Args::finish() const {
  if (!positional_.empty() && !positional_read_)
    throw Error(command_ + ": unexpected argument '" + positional_[0] + "' (options are --name value; see egopd " +
                command_ + " --help)");
  for (const auto& [k, v] : values_)
    if (!read_.count(k)) throw Error(command_ + ": unknown option --" + k + " (see egopd " + command_ + " --help)");
  for (const auto& k : flags_)
    if (!read_.count(k)) throw Error(command_ + ": unknown option --" + k + " (see egopd " + command_ + " --help)");
}

int run_reporting_errors(const char* program, const std::function<int()>& body) {
  try {
    return body();
  } catch (const Interrupted& e) {  // SIGINT/SIGTERM at a safe point: 130 / 143, as a shell reports a signal
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return e.exit_code();
  } catch (...) {
    std::fprintf(stderr, "%s: %s\n", program, current_exception_line().c_str());
  }
  return 1;
}

}  // namespace egopd
