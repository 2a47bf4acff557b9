#pragma once
// The prediction runs behind `egopd predict` and `egopd counterfactual` and the C API (include/egopd.h;
// egopressurediff.md §8-§10): option resolution (built-in synthetic model and clip, sampler/step defaults), the
// pipeline run with progress and cancellation through hooks, the results as arrays, and, on request, the output
// folder (heatmap PNGs, side-by-side MP4, taxels.csv, summary.json). Kept in the pipeline library so the tests drive
// exactly what the CLI and the library run.
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "core/error.h"

namespace egopd {

class EgoPressureDiffPipeline;
class StageTimes;
using PromptFields = std::map<std::string, std::string>;

struct PredictOptions {
  std::string model_dir;  // empty: the built-in synthetic model (created once in a cache folder)
  std::string video;      // clip file or frame folder; empty: the built-in synthetic sample clip
  std::string masks_dir;  // optional hint masks, one image per sampled frame
  std::string meta_path;  // META.json -> prompt fields (exclusive with prompt)
  std::optional<std::string> prompt;  // verbatim prompt
  std::string sampler;                // "" (the model's scheduler), "euler" or "lcm"
  int steps = 0;                      // 0: default (see resolve_steps)
  uint64_t seed = 0;
  int64_t frames = 0;  // 0: the model's default (16)
  int64_t size = 256;
  std::optional<std::pair<float, float>> guidance;  // min, max; default: the model's
  int64_t decode_chunk = 0;                         // 0: all frames at once (also with --low-mem)
  bool low_mem = false;                             // load components one at a time (EgoPressureDiffPipeline)
  std::string template_path;                        // empty: the shipped template
  std::string out_dir;
};

// What a run reports while it works.
struct RunProgress {
  const char* stage = "";  // "encode", "denoise" (after each sampler step), "decode", "write"
  int step = 0, steps = 0;  // denoise: sampler step (1-based) and the number of steps; other stages 0, 0
  double step_seconds = 0;  // denoise: seconds of this step
  double elapsed_seconds = 0;  // since the run (the clip, or the whole counterfactual) started
  int variant = 0, variants = 0;  // counterfactual: prompt variant (1-based) and their number; else 0, 0
};
struct RunHooks {
  std::function<void(const std::string&)> log;       // one line without newline; empty: quiet
  std::function<bool(const RunProgress&)> progress;  // return false to cancel the run; empty: never cancels
  std::string prefix;  // put before the lines and the progress of a clip (batch: "[k/n ID] ")
};
// The commands' output: lines on stderr, the sampler's progress as an updating bar on a terminal (plain lines
// otherwise), and the "decoding" line.
RunHooks stderr_hooks(const std::string& prefix = "");
class StderrProgress {
 public:
  explicit StderrProgress(std::string prefix);
  void operator()(const RunProgress& p);

 private:
  std::string prefix_;
  bool tty_;
  double sum_ = 0;
};

// The progress hook asked to stop: thrown at the next report, nothing half-written is left.
class Cancelled : public Error {
 public:
  explicit Cancelled(const std::string& where);
};

// "MIN,MAX" (or one number for both) -> (min, max); one-line error otherwise.
std::pair<float, float> parse_guidance(const std::string& text);

// Steps to pass to the pipeline: the user's, else 4 when --sampler lcm overrides a model whose own scheduler is
// Euler (the usual distilled-student setting), else 0 (the pipeline's default: model defaults / sampler default).
int resolve_steps(const PredictOptions& o, const std::string& model_scheduler);

// One attribute and its values for counterfactual prompting: FIELD=v1,v2,...; the value "omit" drops the field.
struct VarySpec {
  std::string field;
  std::vector<std::string> values;
};
VarySpec parse_vary(const std::string& text);
// A checked VarySpec from a field and its values (the field must be a prompt field, values non-empty UTF-8).
VarySpec make_vary(const std::string& field, std::vector<std::string> values);
// Folder name of one variant, e.g. weight_355g, weight_omit (file-system safe).
std::string variant_folder_name(const std::string& field, const std::string& formatted_value);

// Folder of the built-in synthetic model, tiny-synthetic-f32-lcm4-seed0-<synthetic_model_id> in $XDG_CACHE_HOME/egopd,
// else ~/.cache/egopd, else (neither writable) the same name with a leading ".egopd-" beside out_dir. Created on first
// use.
std::string default_model_dir(const std::string& out_dir);
// egopd's cache folder ($XDG_CACHE_HOME/egopd, else ~/.cache/egopd), created; empty when neither is writable.
std::string cache_root();

// The model of a prediction run, loaded once (o.model_dir or the built-in synthetic model, o.size, o.template_path,
// o.low_mem) and used for any number of clips.
class PredictModel {
 public:
  explicit PredictModel(const PredictOptions& o, const RunHooks& hooks = stderr_hooks());
  ~PredictModel();
  const std::string& model_dir() const { return model_dir_; }
  bool builtin() const { return builtin_; }
  double load_seconds() const { return load_seconds_; }
  EgoPressureDiffPipeline& pipeline() const { return *pipe_; }

 private:
  std::string model_dir_;
  bool builtin_ = false;
  double load_seconds_ = 0;
  std::unique_ptr<EgoPressureDiffPipeline> pipe_;
};

// One clip's inputs: a video file or frame folder, or source frames in memory (8-bit RGB images of one size, not
// copied: they must live until the run returns), or neither (the built-in sample clip); optional hint masks from a
// folder or in memory (8-bit grey); and the prompt (verbatim, or from metadata fields, or neither: no-text mode).
struct ClipSource {
  std::string video;
  std::string masks_dir;
  std::optional<std::string> prompt;
  std::optional<PromptFields> meta;
  std::vector<cv::Mat> frames;  // in-memory source frames (RGB), exclusive with video
  std::vector<cv::Mat> masks;   // in-memory masks (grey), exclusive with masks_dir
};

struct ClipOutcome {
  int64_t frames = 0, size = 0;
  int num_taxels = 0;
  double mean_total_force_n = 0, peak_total_force_n = 0;
  double seconds = 0;
  std::vector<double> taxels_n;       // [frames, num_taxels] in N, the values of taxels.csv
  std::vector<float> heatmaps;        // [frames, size, size] the drawn heatmaps (heatmap_NNN.png), in [0, 1]
  std::vector<double> total_force_n;  // [frames] sum of the taxels
  std::vector<uint8_t> contact;       // [frames] 1: some taxel in contact
  std::string summary_json;           // summary.json (written or not)
  std::string variant_field, variant_value, variant_folder;  // counterfactual: the variant; else empty
};

// Predicts one clip with a loaded model. With a non-empty out_dir it writes heatmap PNGs, side_by_side.mp4,
// taxels.csv and summary.json into out_dir as a whole (built beside it and renamed into place; an earlier folder is
// replaced, a failed or interrupted run leaves it untouched). SIGINT/SIGTERM are polled after every sampler step
// (throws Interrupted); hooks.progress returning false throws Cancelled.
ClipOutcome predict_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& clip,
                         const std::string& out_dir, const RunHooks& hooks = stderr_hooks());

// Same clip and seed under every prompt variant of `vary` (one encode pass, one denoising run per variant); base
// fields from clip.meta (a verbatim prompt is an error). With a non-empty out_dir: one folder per variant plus
// comparison.png and forces.csv, all appearing together. One outcome per variant.
std::vector<ClipOutcome> counterfactual_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& clip,
                                             const VarySpec& vary, const std::string& out_dir,
                                             const RunHooks& hooks = stderr_hooks());

// Checks of the options that need no model and no clip, before any work (one-line errors naming the flag).
void check_predict_options(const PredictOptions& o);
// The clip of the options (--video, --masks, --prompt, --meta read and parsed).
ClipSource clip_source(const PredictOptions& o);

// The closing lines of a prediction (time, mean and peak force; the output files when out_dir is set).
void log_predict_done(const RunHooks& hooks, const ClipOutcome& c, double load_seconds, bool builtin_model,
                      const std::string& out_dir);

// Run one prediction and write its outputs into o.out_dir (o.out_dir required). Returns 0.
int run_predict(const PredictOptions& o, const RunHooks& hooks = stderr_hooks());
// counterfactual_clip with the options' clip into o.out_dir (required). Returns 0.
int run_counterfactual(const PredictOptions& o, const VarySpec& vary, const RunHooks& hooks = stderr_hooks());

}  // namespace egopd
