#include "core/atomic_file.h"

#include <fcntl.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "core/error.h"
#include "core/interrupt.h"

namespace egopd {
namespace fs = std::filesystem;

AtomicFileWriter::AtomicFileWriter(const std::string& path) : path_(path) {
  tmp_ = path + ".tmp." + std::to_string(::getpid());
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw Error(path + ": cannot write: " + std::strerror(errno));
}

AtomicFileWriter::~AtomicFileWriter() {
  if (fd_ >= 0) {
    ::close(fd_);
    ::unlink(tmp_.c_str());
  }
}

void AtomicFileWriter::write(const void* data, size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  while (size > 0) {
    const ssize_t w = ::write(fd_, p, size);
    if (w < 0) {
      if (errno == EINTR) continue;
      throw Error(path_ + ": write failed: " + std::strerror(errno));
    }
    p += w;
    size -= size_t(w);
  }
}

void AtomicFileWriter::commit() {
  const int fd = fd_;
  fd_ = -1;
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const int err = errno;
    ::unlink(tmp_.c_str());
    throw Error(path_ + ": write failed: " + std::strerror(err));
  }
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) {
    const int err = errno;
    ::unlink(tmp_.c_str());
    throw Error(path_ + ": cannot rename temporary file into place: " + std::strerror(err));
  }
}

void write_file_atomic(const std::string& path, const void* data, size_t size) {
  AtomicFileWriter w(path);
  w.write(data, size);
  w.commit();
}

void write_file_atomic(const std::string& path, const std::string& text) {
  write_file_atomic(path, text.data(), text.size());
}

namespace {

std::string temporary_prefix(const fs::path& target) {
  std::string prefix = ".";  // appended piecewise: GCC 12 warns (-Wrestrict, falsely) on the chained operator+
  prefix += target.filename().string();
  prefix += ".tmp-";
  return prefix;
}

// A folder name without a trailing separator ("out/" -> "out"), so parent and name are the folder's own.
fs::path normal_target(const std::string& target) {
  fs::path p = fs::path(target).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p;
}

void sync_folder(const fs::path& dir) {
  const int fd = ::open(dir.empty() ? "." : dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

AtomicDir::AtomicDir(const std::string& target, const std::string& marker) {
  const fs::path t = normal_target(target);
  if (t.empty() || t.filename() == "." || t.filename() == "..")
    throw Error(target + ": not usable as an output folder name");
  target_ = t.string();
  const fs::path parent = t.parent_path();
  std::error_code ec;
  if (!parent.empty()) fs::create_directories(parent, ec);
  if (!parent.empty() && !fs::is_directory(parent))
    throw Error(parent.string() + ": cannot create the folder that holds " + target_);
  if (fs::exists(t) && !fs::is_directory(t)) throw Error(target_ + ": exists and is not a folder");
  if (fs::is_directory(t) && !fs::is_empty(t, ec) && !fs::exists(t / marker))
    throw Error(target_ + ": exists and is not an earlier output of this command (no " + marker +
                "); it would be replaced as a whole: choose another folder or remove it");
  static std::atomic<int> counter{0};
  for (int attempt = 0;; ++attempt) {
    const fs::path tmp =
        parent / (temporary_prefix(t) + std::to_string(::getpid()) + "-" + std::to_string(counter++));
    if (::mkdir(tmp.c_str(), 0755) == 0) {
      tmp_ = tmp.string();
      return;
    }
    if (errno != EEXIST || attempt > 1000)
      throw Error(target_ + ": cannot create a temporary output folder: " + std::strerror(errno));
  }
}

AtomicDir::~AtomicDir() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(tmp_, ec);
}

std::string AtomicDir::user_facing(const std::string& message) const {
  std::string out = message;
  for (size_t at = out.find(tmp_); at != std::string::npos; at = out.find(tmp_, at + target_.size()))
    out.replace(at, tmp_.size(), target_);
  return out;
}

void AtomicDir::fill_and_commit(const std::function<void(const std::string& dir)>& fill) {
  try {
    fill(tmp_);
  } catch (const Interrupted&) {
    throw;
  } catch (const Error& e) {
    throw Error(user_facing(e.what()));
  }
  throw_if_interrupted("before moving the outputs into place");
  commit();
}

void AtomicDir::commit() {
  if (committed_) return;
  sync_folder(tmp_);  // the files were fsynced by their writers; this makes their names durable
  std::error_code ec;
  if (!fs::exists(target_)) {
    if (::rename(tmp_.c_str(), target_.c_str()) != 0)
      throw Error(target_ + ": cannot move the finished output folder into place: " + std::strerror(errno));
  } else {
#ifdef RENAME_EXCHANGE
    // Swap the finished folder and the old one in one step, then delete the old one (now under the temporary name).
    if (::renameat2(AT_FDCWD, tmp_.c_str(), AT_FDCWD, target_.c_str(), RENAME_EXCHANGE) == 0) {
      committed_ = true;
      fs::remove_all(tmp_, ec);
      sync_folder(fs::path(target_).parent_path());
      return;
    }
#endif
    // No atomic exchange (old kernel or file system): move the old folder aside, then the new one in.
    const std::string old = tmp_ + ".old";
    if (::rename(target_.c_str(), old.c_str()) != 0)
      throw Error(target_ + ": cannot replace the earlier output folder: " + std::strerror(errno));
    if (::rename(tmp_.c_str(), target_.c_str()) != 0) {
      const int err = errno;
      ::rename(old.c_str(), target_.c_str());
      throw Error(target_ + ": cannot move the finished output folder into place: " + std::strerror(err));
    }
    fs::remove_all(old, ec);
  }
  committed_ = true;
  sync_folder(fs::path(target_).parent_path());
}

namespace {
// Removes the entries beside `target` that are its temporaries (AtomicDir's `.<name>.tmp-*`, and with
// writers_too AtomicFileWriter's `<name>.tmp.*` and a cache's `<name>.tmp-*`) and that `abandoned` accepts;
// returns how many.
template <typename Pred>
int remove_temporaries(const fs::path& target, bool writers_too, Pred abandoned) {
  const fs::path t = normal_target(target.string());
  const fs::path parent = t.parent_path().empty() ? fs::path(".") : t.parent_path();
  const std::string dir_prefix = temporary_prefix(t), writer_prefix = t.filename().string() + ".tmp";
  std::error_code ec;
  int removed = 0;
  for (fs::directory_iterator it(parent, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    const bool ours = name.rfind(dir_prefix, 0) == 0 || (writers_too && name.rfind(writer_prefix, 0) == 0);
    if (!ours || !abandoned(it->path())) continue;
    std::error_code rm;
    if (fs::remove_all(it->path(), rm) > 0 && !rm) ++removed;
  }
  return removed;
}
}  // namespace

int remove_stale_temporaries(const std::string& target) {
  return remove_temporaries(target, false, [](const fs::path&) { return true; });
}

namespace {
// The newest modification time of p and, for a folder, of everything in it.
fs::file_time_type newest_change(const fs::path& p) {
  std::error_code ec;
  fs::file_time_type newest = fs::last_write_time(p, ec);
  if (fs::is_directory(p, ec))
    for (fs::recursive_directory_iterator it(p, ec), end; !ec && it != end; it.increment(ec))
      newest = std::max(newest, fs::last_write_time(it->path(), ec));
  return newest;
}
}  // namespace

int remove_abandoned_temporaries(const std::string& path, double idle_seconds) {
  using Duration = fs::file_time_type::duration;
  const auto idle = std::chrono::duration_cast<Duration>(std::chrono::duration<double>(idle_seconds));
  const auto cutoff = fs::file_time_type::clock::now() - idle;
  return remove_temporaries(path, true, [&](const fs::path& p) { return newest_change(p) <= cutoff; });
}

}  // namespace egopd
