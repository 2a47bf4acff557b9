// `egopd batch` (every clip of a manifest, or of one shard, with the model loaded once) and `egopd manifest`
// (a manifest from a dataset tree).
#include <cstdio>
#include <cstdlib>

#include "batch/batch_run.h"
#include "batch/manifest.h"
#include "cli/commands.h"
#include "cli/predict_options.h"
#include "core/error.h"
#include "core/threading.h"

namespace egopd {

int cmd_batch(const Args& a) {
  for (const char* per_clip : {"video", "masks", "meta", "prompt"})
    if (a.has(per_clip))
      throw Error(std::string("batch: --") + per_clip + " is given per clip by the manifest, not on the command line");
  BatchOptions o;
  o.manifest = a.require("manifest");
  o.out_dir = a.get("out", "");
  o.predict = read_predict_options(a);
  if (a.has("shard")) {
    o.shard = parse_shard(a.get("shard", ""));
  } else if (const std::optional<Shard> s = shard_from_slurm_env()) {
    o.shard = *s;
  }
  a.finish();
  // In a Slurm task without --threads or EGOPD_THREADS: the CPUs the task was given.
  const char* slurm_cpus = std::getenv("SLURM_CPUS_PER_TASK");
  if (!a.has("threads") && !std::getenv("EGOPD_THREADS") && slurm_cpus) {
    char* end = nullptr;
    const long n = std::strtol(slurm_cpus, &end, 10);
    if (*end != '\0' || n < 1 || n > 1024)
      throw Error(std::string("SLURM_CPUS_PER_TASK='") + slurm_cpus + "' is not a thread count");
    set_num_threads(int(n));
  }
  const BatchSummary s = run_batch(o);
  if (s.failed > 0) {
    std::fprintf(stderr, "egopd: batch: %lld of %lld clips failed (see %s/*.failed); re-run to retry them\n",
                 static_cast<long long>(s.failed), static_cast<long long>(s.done + s.failed + s.skipped),
                 o.out_dir.c_str());
    return 1;
  }
  return 0;
}

int cmd_manifest(const Args& a) {
  ManifestBuildOptions o;
  o.root = a.require("root");
  o.list = a.get("list", "");
  o.attributes = a.get("attributes", "");
  o.out = a.require("out");
  a.finish();
  const size_t n = build_manifest(o);
  std::fprintf(stderr, "egopd manifest: %zu clips -> %s\n", n, o.out.c_str());
  return 0;
}

}  // namespace egopd
