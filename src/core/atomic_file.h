#pragma once
// Whole-or-nothing outputs: files written to a temporary name and renamed into place, and folders built under a
// temporary name beside their target and swapped in as a whole. An interrupted or failed run leaves the previous
// output (or nothing) and no temporary files.
#include <cstddef>
#include <functional>
#include <string>

namespace egopd {

// Streaming atomic write: data goes to `path.tmp.<pid>`; commit() fsyncs and renames it into place; destroying an
// uncommitted writer removes the temporary file (an interrupted run leaves the old file untouched). Every write,
// fsync, close and rename error is one line naming `path`.
class AtomicFileWriter {
 public:
  explicit AtomicFileWriter(const std::string& path);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;
  void write(const void* data, size_t size);
  void commit();

 private:
  std::string path_, tmp_;
  int fd_ = -1;
};

// Atomic whole-file write: `path.tmp.<pid>` then rename. Used for every output the runtime produces.
void write_file_atomic(const std::string& path, const void* data, size_t size);
void write_file_atomic(const std::string& path, const std::string& text);

// An output folder built whole: files are written into path() (`<parent>/.<name>.tmp-<pid>-<n>`, created here);
// commit() puts it in place of `target`, replacing an earlier folder as a whole (nothing of the old run survives,
// e.g. heatmaps of frames a shorter re-run does not have). Destroying an uncommitted AtomicDir removes the
// temporary folder and everything in it. Only an earlier output is ever replaced: an existing non-empty `target`
// without the file `marker` (e.g. summary.json) is an error here, before any work, so a mistyped --out never
// deletes someone's folder.
class AtomicDir {
 public:
  AtomicDir(const std::string& target, const std::string& marker);
  ~AtomicDir();
  AtomicDir(const AtomicDir&) = delete;
  AtomicDir& operator=(const AtomicDir&) = delete;
  const std::string& path() const { return tmp_; }
  const std::string& target() const { return target_; }
  // `message` with the temporary folder's name replaced by the target's, so errors name the files users know.
  std::string user_facing(const std::string& message) const;
  void commit();
  // Runs fill(path()), then commit(). Errors name the target's files, not the temporary ones; a SIGINT/SIGTERM
  // (core/interrupt.h) that arrives meanwhile is rethrown as is and leaves nothing behind.
  void fill_and_commit(const std::function<void(const std::string& dir)>& fill);

 private:
  std::string target_, tmp_;
  bool committed_ = false;
};

// Temporary folders that AtomicDir would use for `target` (`.<name>.tmp-*` beside it), e.g. left by a killed
// process; removes them and returns how many. Only for a caller that owns `target` (one writer per folder).
int remove_stale_temporaries(const std::string& target);

// Temporaries of `path` (files or folders beside it: AtomicFileWriter's `<name>.tmp.<pid>`, a cache's
// `<name>.tmp-<pid>`, AtomicDir's `.<name>.tmp-*`) in which nothing has changed for idle_seconds: left by a process
// killed outright (SIGKILL, a power cut), which no clean-up of its own could remove. Removes them and returns how
// many. Judged by age, not by process id, so that a live writer on another host sharing the folder (a cluster's home)
// is never touched; a live writer changes its temporary every few seconds, hence the default hour.
int remove_abandoned_temporaries(const std::string& path, double idle_seconds = 3600);

}  // namespace egopd
