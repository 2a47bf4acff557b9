#pragma once
// `egopd batch`: every clip of a manifest (or of one shard of it) with the model loaded once. Each clip's outputs
// appear whole in OUT/<id>/ (a complete folder is skipped, so re-running resumes); a clip that fails leaves
// OUT/<id>.failed (its one-line error) and the batch goes on; SIGINT/SIGTERM stop at the next safe point with
// nothing half-written (the next run resumes).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "pipeline/predict_run.h"

namespace egopd {

struct Shard {
  int64_t index = 0, count = 1;  // this process runs the clips k with k % count == index
};
// "I/N" with 0 <= I < N; the error names --shard.
Shard parse_shard(const std::string& text);
// From SLURM_ARRAY_TASK_ID (minus SLURM_ARRAY_TASK_MIN) and SLURM_ARRAY_TASK_COUNT; nullopt outside an array job.
std::optional<Shard> shard_from_slurm_env();
// Manifest positions of a shard's clips (round robin: balanced, and each clip in exactly one shard).
std::vector<size_t> shard_clips(size_t num_clips, const Shard& s);

struct BatchOptions {
  std::string manifest;
  std::string out_dir;
  Shard shard;
  PredictOptions predict;  // model, sampler, steps, seed, frames, size, ... (video/masks/meta/prompt unused)
};

struct BatchSummary {
  int64_t done = 0, skipped = 0, failed = 0;
  std::vector<int64_t> rss_after_clip;   // resident set size (bytes) after each clip that ran
  std::vector<int64_t> heap_after_clip;  // heap in use (bytes, heap_in_use_bytes) after each clip that ran
};

// Runs the shard; progress and the end-of-run line on stderr. Throws Interrupted on SIGINT/SIGTERM.
BatchSummary run_batch(const BatchOptions& o);

// Marker of a failed clip beside its (absent) output folder.
std::string failed_marker(const std::string& out_dir, const std::string& id);
// A clip's folder is complete when it exists: it is only ever renamed into place whole.
bool clip_done(const std::string& out_dir, const std::string& id);

}  // namespace egopd
