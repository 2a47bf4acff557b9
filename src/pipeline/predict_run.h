#pragma once
// The prediction commands behind `egopd predict` and `egopd counterfactual` (egopressurediff.md §8-§10): option
// resolution (built-in synthetic model and clip, sampler/step defaults), the pipeline run with progress on stderr,
// and the output folder (heatmap PNGs, side-by-side MP4, taxels.csv, summary.json). Kept in the pipeline library so
// the tests drive exactly what the CLI runs.
#include <cstdint>
#include <memory>
#include <optional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace egopd {

class EgoPressureDiffPipeline;
struct StageTimes;
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
// Folder name of one variant, e.g. weight_355g, weight_omit (file-system safe).
std::string variant_folder_name(const std::string& field, const std::string& formatted_value);

// Folder of the built-in synthetic model: $XDG_CACHE_HOME/egopd/..., else ~/.cache/egopd/..., else (not writable)
// .egopd-default-model beside out_dir. Created on first use.
std::string default_model_dir(const std::string& out_dir);
// egopd's cache folder ($XDG_CACHE_HOME/egopd, else ~/.cache/egopd), created; empty when neither is writable.
std::string cache_root();

// The model of a prediction run, loaded once (o.model_dir or the built-in synthetic model, o.size, o.template_path,
// o.low_mem) and used for any number of clips.
class PredictModel {
 public:
  explicit PredictModel(const PredictOptions& o);
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

// One clip's inputs: a video file or frame folder (empty: the built-in sample clip), optional hint masks, and the
// prompt (verbatim, or from metadata fields, or neither: no-text mode).
struct ClipSource {
  std::string video;
  std::string masks_dir;
  std::optional<std::string> prompt;
  std::optional<PromptFields> meta;
};

struct ClipOutcome {
  int64_t frames = 0;
  double mean_total_force_n = 0, peak_total_force_n = 0;
  double seconds = 0;
};

// Predicts one clip with a loaded model and writes heatmap PNGs, side_by_side.mp4, taxels.csv and summary.json
// into out_dir as a whole (built beside it and renamed into place; an earlier folder is replaced, a failed or
// interrupted run leaves it untouched). Progress lines on stderr start with `prefix`. SIGINT/SIGTERM are polled
// after every sampler step (throws Interrupted).
ClipOutcome predict_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& clip,
                         const std::string& out_dir, const std::string& prefix = "");

// Checks of the options that need no model and no clip, before any work (one-line errors naming the flag).
void check_predict_options(const PredictOptions& o);

// Run one prediction and write its outputs into o.out_dir. Returns 0.
int run_predict(const PredictOptions& o);
// Same clip and seed under every prompt variant of `vary` (one encode pass, one denoising run per variant);
// one output folder per variant plus comparison.png and forces.csv in o.out_dir. Returns 0.
int run_counterfactual(const PredictOptions& o, const VarySpec& vary);

}  // namespace egopd
