#pragma once
// Internal to predict_run.cpp and counterfactual_run.cpp: one clip prepared on a loaded model, the reporting of a
// run through its hooks, and the writers of the output folders.
#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/timing.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/predict_run.h"

namespace egopd::detail {

using Clock = std::chrono::steady_clock;
using ojson = nlohmann::ordered_json;

constexpr double kVideoFps = 5;

// Log lines and progress of one run through its hooks; the progress hook may cancel (throws Cancelled).
class Reporter {
 public:
  explicit Reporter(const RunHooks& hooks) : hooks_(hooks), start_(Clock::now()) {}
  void say(const char* fmt, ...) const __attribute__((format(printf, 2, 3)));
  // A stage starts ("encode", "decode", "write"); `variant` of `variants` in a counterfactual run.
  void stage(const char* name) const;
  // After sampler step i of n (1-based): the progress report, then the SIGINT/SIGTERM check; after the last step,
  // the "decode" stage.
  void step(int i, int n, double seconds) const;
  StepCallback step_callback() const {
    return [this](int i, int n, double s) { step(i, n, s); };
  }
  void set_variant(int variant, int variants) { variant_ = variant, variants_ = variants; }
  const std::string& prefix() const { return hooks_.prefix; }

 private:
  void report(RunProgress p, const std::string& where) const;
  const RunHooks& hooks_;
  Clock::time_point start_;
  int variant_ = 0, variants_ = 0;
};

// One clip on a loaded model: resolved settings, the sampled frames and masks, and the stage times so far.
struct Prepared {
  Clock::time_point start;
  const PredictModel* model = nullptr;
  bool builtin_clip = false;
  PipelineSettings settings;
  LoadedClip clip;
  Tensor frames, masks;
  StageTimes times;  // encoding (shared by every prompt)
  EgoPressureDiffPipeline& pipe() const { return model->pipeline(); }
};
// Settings, frames and masks of one clip; the built-in sample clip is saved into work_dir (when not empty).
Prepared prepare_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                      const std::string& work_dir, const Reporter& rep);

// Taxels (N), heatmaps and per-frame forces of one result, the summary still to be filled in.
ClipOutcome outcome_of(const Prepared& p, const EgoPressureDiffPipeline::Result& r);
// Heatmap PNGs, side-by-side video and taxels.csv of one result.
void write_outputs(const std::string& dir, const Prepared& p, const EgoPressureDiffPipeline::Result& r,
                   const ClipOutcome& c);
cv::Mat painted(const EgoPressureDiffPipeline& pipe, const std::vector<double>& h);

ojson timings_json(const StageTimes& t, double total);
ojson summary_json(const PredictOptions& o, const ClipSource& src, const Prepared& p,
                   const EgoPressureDiffPipeline::Shared& sh, const std::optional<std::string>& prompt, bool truncated,
                   const ClipOutcome& c);
// Adds timings and peak RSS to j and stores its text in c.summary_json; writes dir/summary.json when dir is set.
void finish_summary(ojson& j, const std::string& dir, const StageTimes& times, double total, ClipOutcome& c);

void announce_prompt(const Reporter& rep, const std::optional<std::string>& prompt, bool truncated,
                     const std::string& prefix);

}  // namespace egopd::detail
