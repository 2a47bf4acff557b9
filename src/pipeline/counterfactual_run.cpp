// Counterfactual prompting (egopressurediff.md §9): one clip and seed under prompt variants of one field, encoded
// once, denoised once per variant; the variant folders, comparison.png and forces.csv on request.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "pipeline/predict_detail.h"
#include "pipeline/predict_run.h"

namespace egopd {
namespace fs = std::filesystem;
using namespace detail;

namespace {

struct Variant {
  std::string label;   // FIELD=value or FIELD omitted
  std::string folder;  // e.g. weight_355g
  std::string value;   // formatted value, "omit" for a dropped field
  PromptFields fields;
};

std::vector<Variant> make_variants(const PromptFields& base, const VarySpec& vary) {
  std::vector<Variant> out;
  for (const std::string& raw : vary.values) {
    Variant v;
    v.fields = base;
    if (raw == "omit") {
      v.fields.erase(vary.field);
      v.value = "omit";
      v.label = vary.field + " omitted";
    } else {
      // A bare number gets the field's unit (355 -> 355g); anything else is used verbatim.
      char* end = nullptr;
      const double x = std::strtod(raw.c_str(), &end);
      const nlohmann::json value = (*end == '\0' && std::isfinite(x)) ? nlohmann::json(x) : nlohmann::json(raw);
      v.value = format_prompt_field(vary.field, value, "--vary");
      v.fields[vary.field] = v.value;
      v.label = vary.field + "=" + v.value;
    }
    v.folder = variant_folder_name(vary.field, v.value);
    for (const Variant& o : out)
      if (o.folder == v.folder) {
        v.folder += '_';
        v.folder += std::to_string(out.size());
      }
    out.push_back(std::move(v));
  }
  return out;
}

// Rows = variants, columns = uniformly sampled frames; a label strip on the left and a header row on top.
cv::Mat comparison_figure(const std::vector<std::string>& labels, const std::vector<std::vector<cv::Mat>>& cells,
                          const std::vector<int64_t>& columns) {
  const int S = cells[0][0].rows, label_w = 190, header_h = 24;
  const int rows = int(cells.size()), cols = int(columns.size());
  cv::Mat fig(header_h + rows * S, label_w + cols * S, CV_8UC3, cv::Scalar(16, 16, 16));
  const double scale = 0.45;
  for (int c = 0; c < cols; ++c)
    cv::putText(fig, "frame " + std::to_string(columns[size_t(c)]), cv::Point(label_w + c * S + 4, 17),
                cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(230, 230, 230), 1, cv::LINE_AA);
  for (int r = 0; r < rows; ++r) {
    const int y = header_h + r * S;
    cv::putText(fig, labels[size_t(2 * r)], cv::Point(6, y + S / 2 - 4), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
    cv::putText(fig, labels[size_t(2 * r + 1)], cv::Point(6, y + S / 2 + 16), cv::FONT_HERSHEY_SIMPLEX, scale,
                cv::Scalar(170, 200, 255), 1, cv::LINE_AA);
    for (int c = 0; c < cols; ++c) cells[size_t(r)][size_t(c)].copyTo(fig(cv::Rect(label_w + c * S, y, S, S)));
  }
  return fig;
}

int64_t contact_frames(const ClipOutcome& c) { return int64_t(std::count(c.contact.begin(), c.contact.end(), 1)); }

std::string forces_csv(const std::vector<ClipOutcome>& variants) {
  std::string csv = "variant,field,value,mean_total_force_n,peak_total_force_n,contact_frames,seconds\n";
  for (const ClipOutcome& c : variants) {
    std::string quoted = "\"";  // the value is free text (materials, names): CSV-quote it
    for (char ch : c.variant_value) quoted += ch == '"' ? std::string("\"\"") : std::string(1, ch);
    quoted += "\"";
    char nums[160];
    std::snprintf(nums, sizeof nums, ",%.6g,%.6g,%lld,%.3f\n", c.mean_total_force_n, c.peak_total_force_n,
                  static_cast<long long>(contact_frames(c)), c.seconds);
    csv += c.variant_folder + "," + c.variant_field + "," + quoted + nums;
  }
  return csv;
}

// Encodes the clip once and denoises once per variant; with a non-empty root, writes every variant folder,
// comparison.png and forces.csv into it. Logs the closing line.
std::vector<ClipOutcome> counterfactual_into(const std::string& root, const PredictModel& model,
                                             const PredictOptions& o, const ClipSource& src,
                                             const std::vector<Variant>& variants, const VarySpec& vary,
                                             Reporter& rep) {
  Prepared p = prepare_clip(model, o, src, root, rep);
  EgoPressureDiffPipeline& pipe = p.pipe();

  rep.stage("encode");
  rep.say("encoding %lld frames once (VAE, %s, prototype, seed-%llu noise)", static_cast<long long>(p.settings.frames),
          p.masks.empty() ? "no masks" : "masks", static_cast<unsigned long long>(o.seed));
  const EgoPressureDiffPipeline::Shared sh =
      pipe.encode(p.frames, p.masks.empty() ? nullptr : &p.masks, p.settings, &p.times);
  throw_if_interrupted("after encoding");
  const double shared_seconds = p.times.total();
  rep.say("reusing the cached conditioning (RGB latents, mask features, prototype token, initial and step noises) for "
          "all %zu variants; only the prompt changes", variants.size());

  const int64_t F = sh.frames;
  const std::vector<int64_t> columns = uniform_frame_indices(F, std::min<int64_t>(4, F));
  std::vector<std::string> labels;
  std::vector<std::vector<cv::Mat>> cells;
  std::vector<ClipOutcome> outcomes;
  for (size_t k = 0; k < variants.size(); ++k) {
    const Variant& v = variants[k];
    rep.set_variant(int(k + 1), int(variants.size()));
    const auto t0 = Clock::now();
    char prefix[64];
    std::snprintf(prefix, sizeof prefix, "[%zu/%zu] ", k + 1, variants.size());
    rep.say("%s%s", prefix, v.label.c_str());
    StageTimes vt;
    const std::optional<std::string> prompt = pipe.prompt_for(v.fields);
    bool truncated = false;
    const Tensor text = pipe.encode_text(prompt, &truncated, &vt);
    announce_prompt(rep, prompt, truncated, prefix);
    rep.say("%sdenoising: %s sampler, %d steps", prefix, sh.sampler->name(), sh.sampler->num_steps());
    const EgoPressureDiffPipeline::Result r = pipe.run(sh, text, p.settings, rep.step_callback(), &vt);
    ClipOutcome c = outcome_of(p, r);
    c.variant_field = vary.field, c.variant_value = v.value, c.variant_folder = v.folder;
    const std::string dir = root.empty() ? "" : (fs::path(root) / v.folder).string();
    if (!dir.empty()) {
      rep.stage("write");
      ScopedStage st(&vt, "write");
      write_outputs(dir, p, r, c);
      std::vector<cv::Mat> row;
      for (int64_t col : columns) row.push_back(painted(pipe, r.frames[size_t(col)].h_std));
      cells.push_back(std::move(row));
      char force[64];
      std::snprintf(force, sizeof force, "mean %.2f N", c.mean_total_force_n);
      labels.push_back(v.label);
      labels.push_back(force);
    }
    ojson j = summary_json(o, src, p, sh, prompt, truncated, c);
    j["variant"] = {{"field", vary.field}, {"value", v.value}};
    j["shared_timings_s"] = timings_json(p.times, shared_seconds);
    finish_summary(j, dir, vt, seconds_since(t0), c);
    std::string stages;
    for (const auto& [name, s] : vt.entries()) {
      char b[64];
      std::snprintf(b, sizeof b, "%s%s %.2f s", stages.empty() ? "" : ", ", name.c_str(), s);
      stages += b;
    }
    rep.say("%s%s: %.2f s (%s)", prefix, v.folder.c_str(), c.seconds, stages.c_str());
    outcomes.push_back(std::move(c));
  }
  rep.set_variant(0, 0);

  if (!root.empty()) {
    write_png_atomic((fs::path(root) / "comparison.png").string(), comparison_figure(labels, cells, columns));
    write_file_atomic((fs::path(root) / "forces.csv").string(), forces_csv(outcomes));
  }
  double per_variant = 0;
  for (const ClipOutcome& c : outcomes) per_variant += c.seconds;
  rep.say("done in %.1f s: loading + encoding %.2f s once, %zu variants %.2f s (%.2f s each)",
          model.load_seconds() + seconds_since(p.start), shared_seconds, variants.size(), per_variant,
          per_variant / double(variants.size()));
  return outcomes;
}

}  // namespace

std::vector<ClipOutcome> counterfactual_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                                             const VarySpec& vary, const std::string& out_dir, const RunHooks& hooks) {
  if (src.prompt) throw Error("counterfactual varies prompt fields: give --meta (or nothing), not --prompt");
  if (vary.values.empty()) throw Error("--vary needs at least one value");
  const PromptFields base = src.meta ? *src.meta : PromptFields{};
  const std::vector<Variant> variants = make_variants(base, vary);
  Reporter rep(hooks);
  if (out_dir.empty()) return counterfactual_into("", model, o, src, variants, vary, rep);
  AtomicDir out(out_dir, "forces.csv");  // every variant, the figure and forces.csv appear together or not at all
  std::vector<ClipOutcome> outcomes;
  out.fill_and_commit([&](const std::string& dir) { outcomes = counterfactual_into(dir, model, o, src, variants, vary, rep); });
  rep.say("outputs in %s: one folder per variant (%s, ...), comparison.png, forces.csv%s", out_dir.c_str(),
          variants[0].folder.c_str(), model.builtin() ? " (synthetic model: forces not meaningful)" : "");
  return outcomes;
}

int run_counterfactual(const PredictOptions& o, const VarySpec& vary, const RunHooks& hooks) {
  if (o.out_dir.empty()) throw Error("--out is required");
  if (o.prompt) throw Error("counterfactual varies prompt fields: give --meta (or nothing), not --prompt");
  if (vary.values.empty()) throw Error("--vary needs at least one value");
  install_interrupt_handlers();
  check_predict_options(o);
  const ClipSource src = clip_source(o);
  const PredictModel model(o, hooks);
  counterfactual_clip(model, o, src, vary, o.out_dir, hooks);
  return 0;
}

}  // namespace egopd
