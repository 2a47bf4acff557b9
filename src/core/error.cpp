#include "core/error.h"

#include <exception>
#include <filesystem>
#include <new>

#include <nlohmann/json.hpp>

namespace egopd {

std::string current_exception_line() {
  try {
    throw;
  } catch (const std::bad_alloc&) {
    return "out of memory";
  } catch (const std::filesystem::filesystem_error& e) {  // the library's own wording, in our one-line form
    return std::string(e.path1().empty() ? "file system" : e.path1().string()) + ": " + e.code().message();
  } catch (const nlohmann::json::exception& e) {  // never "[json.exception...]": JSON that reached no reader's check
    return "malformed or non-UTF-8 JSON data (JSON error " + std::to_string(e.id) + ")";
  } catch (const std::exception& e) {  // egopd::Error and anything else: already one line
    return e.what();
  } catch (...) {
    return "unknown internal error";
  }
}

}  // namespace egopd
