#include "core/install_dirs.h"

#include <dlfcn.h>

#include <algorithm>
#include <system_error>

namespace egopd {
namespace fs = std::filesystem;

std::vector<fs::path> installed_data_candidates(const std::string& sub) {
  std::vector<fs::path> out;
  const auto add = [&](const fs::path& prefix) {
    const fs::path p = prefix / "share" / "egopd" / sub;
    if (std::find(out.begin(), out.end(), p) == out.end()) out.push_back(p);
  };
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) add(exe.parent_path().parent_path());
  Dl_info info;
  if (dladdr(reinterpret_cast<void*>(&installed_data_candidates), &info) != 0 && info.dli_fname) {
    const fs::path lib = fs::absolute(info.dli_fname, ec);
    if (!ec && lib != exe) {
      add(lib.parent_path().parent_path());                // PREFIX/lib/libegopd.so
      add(lib.parent_path().parent_path().parent_path());  // PREFIX/lib/x86_64-linux-gnu/libegopd.so
    }
  }
  return out;
}

}  // namespace egopd
