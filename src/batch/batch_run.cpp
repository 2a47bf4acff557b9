#include "batch/batch_run.h"

#include <cerrno>
#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <new>

#include "batch/manifest.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/memory.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// A non-negative integer of an environment variable; nullopt when unset, an error naming it when malformed.
std::optional<int64_t> env_int(const char* name) {
  const char* v = std::getenv(name);
  if (!v || !*v) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long long x = std::strtoll(v, &end, 10);
  if (*end != '\0' || errno || x < 0) throw Error(std::string(name) + "='" + v + "' is not a non-negative integer");
  return x;
}

void log_line(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
void log_line(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  std::fputs("egopd batch: ", stderr);
  std::vfprintf(stderr, fmt, ap);
  va_end(ap);
  std::fputc('\n', stderr);
  std::fflush(stderr);
}

}  // namespace

Shard parse_shard(const std::string& text) {
  const size_t slash = text.find('/');
  Shard s;
  try {
    size_t a = 0, b = 0;
    if (slash == std::string::npos) throw std::invalid_argument("no slash");
    const std::string i = text.substr(0, slash), n = text.substr(slash + 1);
    s.index = std::stoll(i, &a);
    s.count = std::stoll(n, &b);
    if (a != i.size() || b != n.size() || i[0] == '-' || i[0] == '+' || n[0] == '+') throw std::invalid_argument("");
  } catch (const std::exception&) {
    throw Error("--shard expects I/N (e.g. 0/4), got '" + text + "'");
  }
  if (s.count < 1 || s.index < 0 || s.index >= s.count)
    throw Error("--shard " + text + ": needs 0 <= I < N");
  return s;
}

std::optional<Shard> shard_from_slurm_env() {
  const std::optional<int64_t> id = env_int("SLURM_ARRAY_TASK_ID");
  if (!id) return std::nullopt;
  const std::optional<int64_t> count = env_int("SLURM_ARRAY_TASK_COUNT");
  const int64_t min = env_int("SLURM_ARRAY_TASK_MIN").value_or(0);
  if (!count || *count < 1) throw Error("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not");
  Shard s{*id - min, *count};
  if (s.index < 0 || s.index >= s.count)
    throw Error("array task " + std::to_string(*id) + " is outside 0.." + std::to_string(*count - 1) +
                " after SLURM_ARRAY_TASK_MIN: submit the array as --array=0-" + std::to_string(*count - 1));
  return s;
}

std::vector<size_t> shard_clips(size_t num_clips, const Shard& s) {
  std::vector<size_t> out;
  for (size_t k = size_t(s.index); k < num_clips; k += size_t(s.count)) out.push_back(k);
  return out;
}

std::string failed_marker(const std::string& out_dir, const std::string& id) {
  return (fs::path(out_dir) / (id + ".failed")).string();
}

bool clip_done(const std::string& out_dir, const std::string& id) {
  return fs::is_directory(fs::path(out_dir) / id);
}

BatchSummary run_batch(const BatchOptions& o) {
  const Clock::time_point start = Clock::now();
  install_interrupt_handlers();
  const Manifest m = read_manifest(o.manifest);
  PredictOptions po = o.predict;
  po.out_dir = o.out_dir;
  check_predict_options(po);
  std::error_code ec;
  fs::create_directories(o.out_dir, ec);
  if (ec || !fs::is_directory(o.out_dir)) throw Error(o.out_dir + ": cannot create output folder");

  const std::vector<size_t> mine = shard_clips(m.clips.size(), o.shard);
  std::vector<size_t> todo;
  for (size_t k : mine)
    if (!clip_done(o.out_dir, m.clips[k].id)) todo.push_back(k);
  BatchSummary sum;
  sum.skipped = int64_t(mine.size() - todo.size());
  const int64_t n = int64_t(mine.size());
  log_line("%s: shard %lld/%lld holds %lld of %zu clips, %lld already done -> %s", o.manifest.c_str(),
           static_cast<long long>(o.shard.index), static_cast<long long>(o.shard.count), static_cast<long long>(n),
           m.clips.size(), static_cast<long long>(sum.skipped), o.out_dir.c_str());
  if (todo.empty()) {
    log_line("%lld done, %lld skipped, 0 failed: nothing to do", 0LL, static_cast<long long>(sum.skipped));
    return sum;
  }

  const PredictModel model(po);  // once for every clip of the shard
  log_line("model loaded in %.1f s", model.load_seconds());
  int64_t k = sum.skipped;
  const Clock::time_point clips_start = Clock::now();
  for (size_t i : todo) {
    const ManifestClip& c = m.clips[i];
    ++k;
    throw_if_interrupted("before clip " + std::to_string(k) + " of " + std::to_string(n));
    const std::string dir = (fs::path(o.out_dir) / c.id).string();
    remove_stale_temporaries(dir);  // left by a killed or preempted earlier run of this shard
    char prefix[256];
    std::snprintf(prefix, sizeof prefix, "[%lld/%lld %s] ", static_cast<long long>(k), static_cast<long long>(n),
                  c.id.c_str());
    const Clock::time_point t = Clock::now();
    try {
      predict_clip(model, po, c.source(), dir, stderr_hooks(prefix));
      fs::remove(failed_marker(o.out_dir, c.id), ec);
      ++sum.done;
      log_line("done %s (%lld/%lld) in %.1f s", c.id.c_str(), static_cast<long long>(k), static_cast<long long>(n),
               seconds_since(t));
    } catch (const Interrupted&) {
      throw;
    } catch (const std::bad_alloc&) {
      ++sum.failed;
      write_file_atomic(failed_marker(o.out_dir, c.id), "out of memory\n");
      log_line("FAILED %s (%lld/%lld): out of memory", c.id.c_str(), static_cast<long long>(k),
               static_cast<long long>(n));
    } catch (const std::exception& e) {
      ++sum.failed;
      write_file_atomic(failed_marker(o.out_dir, c.id), std::string(e.what()) + "\n");
      log_line("FAILED %s (%lld/%lld): %s", c.id.c_str(), static_cast<long long>(k), static_cast<long long>(n),
               e.what());
    }
    sum.rss_after_clip.push_back(int64_t(current_rss_bytes()));
    sum.heap_after_clip.push_back(int64_t(heap_in_use_bytes()));
  }
  const double clip_seconds = seconds_since(clips_start), total = seconds_since(start);
  // Throughput counts clips that were done, over the whole run including the model load.
  log_line("%lld done, %lld skipped, %lld failed in %.1f s (model load %.1f s); %.1f clips/hour (%.1f s per clip)",
           static_cast<long long>(sum.done), static_cast<long long>(sum.skipped), static_cast<long long>(sum.failed),
           total, model.load_seconds(), sum.done > 0 ? 3600.0 * double(sum.done) / total : 0.0,
           sum.done > 0 ? clip_seconds / double(sum.done + sum.failed) : 0.0);
  return sum;
}

}  // namespace egopd
