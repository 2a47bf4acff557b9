#include "cli/args.h"

#include <cstdio>
#include <cstdlib>
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

int64_t Args::get_int(const std::string& name, int64_t fallback) const {
  std::string v = get(name, "");
  if (v.empty()) return fallback;
  char* end = nullptr;
  long long x = std::strtoll(v.c_str(), &end, 10);
  if (*end != '\0') throw Error(command_ + ": option --" + name + " expects an integer, got '" + v + "'");
  return x;
}

double Args::get_double(const std::string& name, double fallback) const {
  std::string v = get(name, "");
  if (v.empty()) return fallback;
  char* end = nullptr;
  double x = std::strtod(v.c_str(), &end);
  if (*end != '\0') throw Error(command_ + ": option --" + name + " expects a number, got '" + v + "'");
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
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: out of memory\n", program);
  } catch (const std::exception& e) {  // egopd::Error and anything else: already one line
    std::fprintf(stderr, "%s: %s\n", program, e.what());
  }
  return 1;
}

}  // namespace egopd
