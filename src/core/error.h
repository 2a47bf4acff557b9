#pragma once
// One exception type for every user-facing failure: the message is a single line that names the file,
// tensor or field at fault. The CLI prints it as "egopd: <message>" and exits non-zero.
#include <stdexcept>
#include <string>

namespace egopd {

class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& msg) : std::runtime_error(msg) {}
};

// The one-line message of the exception being handled (call inside a catch block): egopd::Error's own line, and
// the same form for out-of-memory, file-system and JSON library errors. Used by the commands and the C API.
std::string current_exception_line();

// Internal invariant check (programming error, not bad input); still a clean one-line error, never UB.
#define EGOPD_CHECK(cond, msg)                                                                        \
  do {                                                                                                \
    if (!(cond)) throw ::egopd::Error(std::string("internal check failed: ") + (msg) + " (" #cond ")"); \
  } while (0)

}  // namespace egopd
