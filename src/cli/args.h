#pragma once
// Command-line options: `--name value`, `--name=value` and boolean `--flag`. Every option a command reads is
// declared by reading it; finish() rejects any option that was given but never read (typos are errors).
#include <climits>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

namespace egopd {

class Args {
 public:
  Args(std::string command, const std::vector<std::string>& argv);
  const std::string& command() const { return command_; }
  bool has(const std::string& name) const;
  std::string get(const std::string& name, const std::string& fallback) const;
  std::string require(const std::string& name) const;
  // Integers are taken exactly: digits (and a leading '-'), nothing else, never clamped; the error names the flag
  // and its bounds.
  int64_t get_int(const std::string& name, int64_t fallback, int64_t lo = INT64_MIN, int64_t hi = INT64_MAX) const;
  uint64_t get_uint64(const std::string& name, uint64_t fallback) const;  // 0..2^64-1 (seeds)
  double get_double(const std::string& name, double fallback) const;     // finite
  bool flag(const std::string& name) const;  // present without value
  // Positional arguments; a command that never asks for them rejects any (finish()).
  const std::vector<std::string>& positional() const {
    positional_read_ = true;
    return positional_;
  }
  void finish() const;  // error on options given but not read, and on positional arguments nobody took

 private:
  std::string command_;
  std::map<std::string, std::string> values_;
  std::set<std::string> flags_;
  std::vector<std::string> positional_;
  mutable std::set<std::string> read_;
  mutable bool positional_read_ = false;
};

// Runs a command-line program's body: any failure becomes one line "<program>: <message>" on stderr and exit code 1
// (130 / 143 after SIGINT / SIGTERM).
int run_reporting_errors(const char* program, const std::function<int()>& body);

}  // namespace egopd
