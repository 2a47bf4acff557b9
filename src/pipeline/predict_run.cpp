#include "pipeline/predict_run.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <system_error>

#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/utf8.h"
#include "pressure/hand_template.h"
#include "core/memory.h"
#include "core/safetensors.h"
#include "core/timing.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/synthetic_model.h"
#include "pressure/pressure.h"
#include "scheduler/sampler.h"

namespace egopd {
namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

namespace {

// The built-in demo model: the "tiny" preset as a 4-step AnimateLCM student, so the demo stays within seconds.
// The cache folder name encodes every parameter, so a change here never reuses a stale directory.
constexpr uint64_t kBuiltinSeed = 0;
constexpr int kBuiltinLcmSteps = 4;
constexpr DType kBuiltinDType = DType::F32;
constexpr const char* kBuiltinName = "tiny-synthetic-f32-lcm4-seed0";
constexpr double kVideoFps = 5;

void say(const char* fmt, ...) __attribute__((format(printf, 1, 2)));
void say(const char* fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  std::vfprintf(stderr, fmt, ap);
  va_end(ap);
  std::fputc('\n', stderr);
  std::fflush(stderr);
}

// Sampler progress on stderr: an updating bar on a terminal, plain lines otherwise (logs, pipes).
class StepProgress {
 public:
  explicit StepProgress(std::string prefix) : prefix_(std::move(prefix)), tty_(::isatty(2) != 0) {}
  void operator()(int i, int n, double seconds) {
    sum_ += seconds;
    const double per = sum_ / i, eta = per * (n - i);
    if (tty_) {
      constexpr int kWidth = 24;
      const int fill = int(std::lround(double(kWidth) * i / n));
      const std::string bar = std::string(size_t(fill), '#') + std::string(size_t(kWidth - fill), ' ');
      const long e = std::lround(eta);
      std::fprintf(stderr, "\r%sstep %d/%d [%s] %.2f s/it ETA %ld:%02ld\033[K", prefix_.c_str(), i, n, bar.c_str(), per,
                   e / 60, e % 60);
      if (i == n) std::fputc('\n', stderr);
    } else {
      std::fprintf(stderr, "%sstep %d/%d %.2f s/it ETA %.0f s\n", prefix_.c_str(), i, n, per, eta);
    }
    if (i == n) std::fprintf(stderr, "%sdecoding %s\n", prefix_.c_str(), "(temporal VAE) and reading out taxels");
    std::fflush(stderr);
    throw_if_interrupted("after step " + std::to_string(i) + " of " + std::to_string(n));
  }

 private:
  std::string prefix_;
  bool tty_;
  double sum_ = 0;
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

void require_exists(const std::string& path, const std::string& what) {
  if (!path.empty() && !fs::exists(path)) throw Error(path + ": " + what + " does not exist");
}

std::string model_scheduler_name(const std::string& model_dir) {
  const fs::path cfg = fs::path(model_dir) / "scheduler";
  if (!fs::is_directory(cfg)) return "";  // the pipeline reports the missing part
  return load_sampler(cfg.string())->name();
}

}  // namespace

void check_predict_options(const PredictOptions& o) {
  if (o.out_dir.empty()) throw Error("--out is required");
  if (o.size < 64 || o.size % 64) throw Error("--size must be a positive multiple of 64 (got " + std::to_string(o.size) + ")");
  if (o.prompt && !o.meta_path.empty()) throw Error("give either --prompt or --meta, not both");
  if (o.steps < 0) throw Error("--steps must be positive");
  if (o.frames < 0) throw Error("--frames must be at least 1");
  if (o.decode_chunk < 0) throw Error("--decode-chunk must be positive");
  if (!o.sampler.empty() && o.sampler != "euler" && o.sampler != "lcm")
    throw Error("--sampler must be euler or lcm (got '" + o.sampler + "')");
  // Prompts and paths go into summary.json: invalid UTF-8 is rejected now, not by the JSON writer at the end.
  if (o.prompt && !is_valid_utf8(*o.prompt)) throw Error("--prompt is not valid UTF-8 text");
  for (const auto& [flag, path] : {std::pair<const char*, const std::string*>{"--model", &o.model_dir},
                                   {"--video", &o.video}, {"--masks", &o.masks_dir}, {"--meta", &o.meta_path},
                                   {"--template", &o.template_path}, {"--out", &o.out_dir}})
    if (!is_valid_utf8(*path)) throw Error(std::string(flag) + ": the path is not valid UTF-8");
  require_exists(o.model_dir, "model directory");
  require_exists(o.video, "video file or frame folder");
  require_exists(o.masks_dir, "mask folder");
  require_exists(o.meta_path, "metadata file");
  require_exists(o.template_path, "hand template");
  if (o.template_path.empty()) default_template_path();  // EGOPD_TEMPLATE naming a missing file fails now
}

namespace {

// Settings, frames and masks of one clip; the built-in sample clip is saved into work_dir.
Prepared prepare_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                      const std::string& work_dir, const std::string& prefix) {
  Prepared p;
  p.start = Clock::now();
  p.model = &model;
  require_exists(src.video, "video file or frame folder");
  require_exists(src.masks_dir, "mask folder");
  PipelineSettings& s = p.settings;
  s = p.pipe().settings_from_defaults();
  if (o.frames > 0) s.frames = o.frames;
  s.sampler = o.sampler;
  s.steps = resolve_steps(o, model_scheduler_name(model.model_dir()));
  s.seed = o.seed;
  if (o.guidance) s.min_guidance = o.guidance->first, s.max_guidance = o.guidance->second;
  s.decode_chunk = o.decode_chunk;

  const int S = int(o.size);
  p.builtin_clip = src.video.empty();
  if (p.builtin_clip) {
    const std::string sample = (fs::path(work_dir) / "sample_clip.mp4").string();
    p.clip.rgb = synthetic_sample_clip(int(s.frames), S);
    p.clip.source_frames = s.frames;
    for (int64_t i = 0; i < s.frames; ++i) p.clip.source_indices.push_back(i);
    std::vector<cv::Mat> bgr;
    for (const cv::Mat& m : p.clip.rgb) {
      cv::Mat b;
      cv::cvtColor(m, b, cv::COLOR_RGB2BGR);
      bgr.push_back(b);
    }
    write_video_atomic(sample, bgr, kVideoFps);
    say("%sclip: built-in SYNTHETIC sample clip (%lld frames, saved as sample_clip.mp4)", prefix.c_str(),
        static_cast<long long>(s.frames));
  } else {
    p.clip = load_clip(src.video, s.frames, S);
    say("%sclip: %s (%lld frames, %lld sampled)", prefix.c_str(), src.video.c_str(),
        static_cast<long long>(p.clip.source_frames), static_cast<long long>(s.frames));
  }
  p.frames = frames_to_tensor(p.clip.rgb);
  if (!src.masks_dir.empty()) p.masks = load_masks(src.masks_dir, p.clip, S);
  return p;
}

struct FrameForces {
  std::vector<double> total_n;  // per frame: sum of the 162 taxels in N
  std::vector<bool> contact;    // per frame: any taxel in contact
  double mean() const {
    double m = 0;
    for (double v : total_n) m += v;
    return total_n.empty() ? 0 : m / double(total_n.size());
  }
  double peak() const { return total_n.empty() ? 0 : *std::max_element(total_n.begin(), total_n.end()); }
};

cv::Mat painted(const EgoPressureDiffPipeline& pipe, const std::vector<double>& h) {
  const int S = int(pipe.size());
  HeatmapPaintOptions opt;
  opt.order = ChannelOrder::BGR;
  std::vector<uint8_t> px = paint_heatmap(h, S, pipe.renderer().outline_canvas(), opt);
  return cv::Mat(S, S, CV_8UC3, px.data()).clone();
}

std::string numbered(const char* stem, size_t i, const char* ext) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s_%03zu.%s", stem, i, ext);
  return buf;
}

// Heatmap PNGs, side-by-side video and taxels.csv of one result; returns the per-frame forces.
FrameForces write_outputs(const std::string& dir, const Prepared& p, const EgoPressureDiffPipeline::Result& r) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (!fs::is_directory(dir)) throw Error(dir + ": cannot create output folder");
  FrameForces ff;
  std::vector<std::vector<double>> taxels;
  std::vector<cv::Mat> side;
  for (size_t f = 0; f < r.frames.size(); ++f) {
    const PressureRenderer::Frame& fr = r.frames[f];
    cv::Mat heat = painted(p.pipe(), fr.h_std);
    write_png_atomic((fs::path(dir) / numbered("heatmap", f, "png")).string(), heat);
    cv::Mat rgb_bgr, pair;
    cv::cvtColor(p.clip.rgb[f], rgb_bgr, cv::COLOR_RGB2BGR);
    cv::hconcat(rgb_bgr, heat, pair);
    side.push_back(pair);
    taxels.push_back(fr.p);
    double total = 0;
    bool contact = false;
    for (double v : fr.p) total += kPressureMax * v, contact = contact || in_contact(v);
    ff.total_n.push_back(total);
    ff.contact.push_back(contact);
  }
  write_video_atomic((fs::path(dir) / "side_by_side.mp4").string(), side, kVideoFps);
  write_taxel_csv((fs::path(dir) / "taxels.csv").string(), newtons_from_normalized(taxels));
  return ff;
}

ojson timings_json(const StageTimes& t, double total) {
  ojson j = ojson::object();
  for (const auto& [k, v] : t.entries()) j[k] = v;
  j["total"] = total;
  return j;
}

ojson summary_json(const PredictOptions& o, const ClipSource& src, const Prepared& p,
                   const EgoPressureDiffPipeline::Shared& sh, const std::optional<std::string>& prompt, bool truncated,
                   const FrameForces& ff) {
  ojson j;
  j["prompt"] = prompt ? ojson(*prompt) : ojson(nullptr);
  j["prompt_truncated"] = truncated;
  j["seed"] = o.seed;
  j["sampler"] = sh.sampler->name();
  j["steps"] = sh.sampler->num_steps();
  j["frames"] = sh.frames;
  j["size"] = p.pipe().size();
  j["guidance"] = {p.settings.min_guidance, p.settings.max_guidance};
  j["low_mem"] = o.low_mem;
  j["decode_chunk"] = o.decode_chunk > 0 ? o.decode_chunk : sh.frames;
  j["model_dir"] = p.model->model_dir();
  j["model_synthetic"] = p.model->builtin();
  j["video"] = p.builtin_clip ? ojson("sample_clip.mp4 (built-in synthetic clip)") : ojson(src.video);
  j["masks"] = src.masks_dir.empty() ? ojson(nullptr) : ojson(src.masks_dir);
  const HandTemplate& t = p.pipe().hand_template();
  j["template"] = {{"name", t.name()}, {"synthetic", t.synthetic()}};
  ojson frames = ojson::array();
  for (size_t f = 0; f < ff.total_n.size(); ++f)
    frames.push_back({{"frame", f},
                      {"source_index", p.clip.source_indices[f]},
                      {"total_force_n", ff.total_n[f]},
                      {"contact", bool(ff.contact[f])}});
  j["mean_total_force_n"] = ff.mean();
  j["peak_total_force_n"] = ff.peak();
  j["per_frame"] = frames;
  return j;
}

void finish_summary(ojson& j, const std::string& dir, const StageTimes& times, double total) {
  j["timings_s"] = timings_json(times, total);
  j["peak_rss_bytes"] = peak_rss_bytes();
  write_file_atomic((fs::path(dir) / "summary.json").string(), j.dump(2) + "\n");
}

std::optional<std::string> prompt_of(const ClipSource& src, const EgoPressureDiffPipeline& pipe) {
  if (src.prompt) return src.prompt;
  if (src.meta) return pipe.prompt_for(*src.meta);
  return std::nullopt;
}

ClipSource clip_source(const PredictOptions& o) {
  ClipSource src{o.video, o.masks_dir, o.prompt, std::nullopt};
  if (!o.meta_path.empty()) src.meta = load_prompt_fields(o.meta_path);
  return src;
}

void announce_prompt(const std::optional<std::string>& prompt, bool truncated, const std::string& prefix) {
  if (prompt) say("%sprompt: \"%s\"", prefix.c_str(), prompt->c_str());
  else say("%sno prompt: no-text mode", prefix.c_str());
  if (truncated) say("%swarning: the prompt is longer than 77 CLIP tokens and was truncated", prefix.c_str());
}

}  // namespace

std::pair<float, float> parse_guidance(const std::string& text) {
  const auto bad = [&] { return Error("--guidance expects MIN,MAX (e.g. 1,3) or one number, got '" + text + "'"); };
  const auto num = [&](const std::string& s) {
    if (s.empty()) throw bad();
    char* end = nullptr;
    const double v = std::strtod(s.c_str(), &end);
    if (*end != '\0' || !std::isfinite(v) || v < 0) throw bad();
    return float(v);
  };
  const size_t comma = text.find(',');
  if (comma == std::string::npos) {
    const float v = num(text);
    return {v, v};
  }
  if (text.find(',', comma + 1) != std::string::npos) throw bad();
  return {num(text.substr(0, comma)), num(text.substr(comma + 1))};
}

int resolve_steps(const PredictOptions& o, const std::string& model_scheduler) {
  if (o.steps > 0) return o.steps;
  if (o.sampler == "lcm" && model_scheduler == "euler") return 4;
  return 0;
}

VarySpec parse_vary(const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size())
    throw Error("--vary expects FIELD=v1,v2,... (e.g. weight=1,355,1000,omit), got '" + text + "'");
  VarySpec v;
  v.field = text.substr(0, eq);
  // The library's own field list decides which names are prompt attributes.
  if (!prompt_fields_from_json(nlohmann::json{{v.field, "x"}}, "--vary").count(v.field))
    throw Error("--vary: '" + v.field +
                "' is not a prompt field (obj_name, weight, material, gender, age, subj_weight, bodyfat)");
  std::string rest = text.substr(eq + 1);
  size_t start = 0;
  while (start <= rest.size()) {
    const size_t c = std::min(rest.find(',', start), rest.size());
    const std::string item = rest.substr(start, c - start);
    if (item.empty()) throw Error("--vary: empty value in '" + text + "'");
    v.values.push_back(item);
    start = c + 1;
  }
  return v;
}

std::string variant_folder_name(const std::string& field, const std::string& value) {
  std::string out = field + "_";
  for (char c : value) {
    if (std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '-') out += c;
    else if (c == '%') out += "pct";
    else if (out.back() != '_') out += '_';
  }
  while (out.size() > field.size() + 1 && out.back() == '_') out.pop_back();
  return out;
}

std::string cache_root() {
  std::string cache;
  if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x) cache = x;
  else if (const char* h = std::getenv("HOME"); h && *h) cache = (fs::path(h) / ".cache").string();
  if (cache.empty()) return "";
  const fs::path root = fs::path(cache) / "egopd";
  std::error_code ec;
  fs::create_directories(root, ec);
  if (fs::is_directory(root) && ::access(root.c_str(), W_OK) == 0) return root.string();
  return "";
}

std::string default_model_dir(const std::string& out_dir) {
  const std::string root = cache_root();
  if (!root.empty()) return (fs::path(root) / kBuiltinName).string();
  // Beside the output folder, not in it: the output folder is replaced as a whole by each run.
  const fs::path parent = fs::path(out_dir).lexically_normal().parent_path();
  return ((parent.empty() ? fs::path(".") : parent) / ".egopd-default-model").string();
}

PredictModel::PredictModel(const PredictOptions& o) {
  const auto start = Clock::now();
  check_predict_options(o);
  builtin_ = o.model_dir.empty();
  model_dir_ = builtin_ ? default_model_dir(o.out_dir) : o.model_dir;
  if (builtin_) {
    if (!fs::exists(fs::path(model_dir_) / "model_index.json")) {
      say("creating the built-in synthetic model (tiny preset, random weights) in %s", model_dir_.c_str());
      // Built beside its place and moved in whole: parallel runs (batch array tasks) never see half a model; the
      // model is deterministic, so when another run got there first its copy is as good as ours.
      AtomicDir tmp(model_dir_, "model_index.json");
      write_synthetic_model(tmp.path(), "tiny", kBuiltinSeed, kBuiltinDType, kBuiltinLcmSteps);
      if (!fs::exists(fs::path(model_dir_) / "model_index.json")) tmp.commit();
    }
    say("model: built-in SYNTHETIC model %s (random weights: the pressures are NOT meaningful)", model_dir_.c_str());
  }
  say("loading model %s (%lldx%lld)", model_dir_.c_str(), static_cast<long long>(o.size),
      static_cast<long long>(o.size));
  if (o.low_mem) say("low-memory mode: components are loaded one at a time and released after use");
  pipe_ = std::make_unique<EgoPressureDiffPipeline>(model_dir_, o.size, o.template_path, o.low_mem);
  const HandTemplate& t = pipe_->hand_template();
  say("hand template: %s%s", t.name().c_str(), t.synthetic() ? " (SYNTHETIC layout, not the real glove)" : "");
  if (!pipe_->renderer().warnings().empty())
    say("warning: %zu template sensors lie outside the hand region (first: %s)", pipe_->renderer().warnings().size(),
        pipe_->renderer().warnings()[0].c_str());
  load_seconds_ = seconds_since(start);
}

PredictModel::~PredictModel() = default;

ClipOutcome predict_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                         const std::string& out_dir, const std::string& prefix) {
  AtomicDir out(out_dir, "summary.json");
  Prepared p = prepare_clip(model, o, src, out.path(), prefix);
  EgoPressureDiffPipeline& pipe = p.pipe();
  StageTimes& times = p.times;
  const std::optional<std::string> prompt = prompt_of(src, pipe);
  bool truncated = false;
  const Tensor text = pipe.encode_text(prompt, &truncated, &times);
  announce_prompt(prompt, truncated, prefix);
  throw_if_interrupted("before encoding");

  say("%sencoding %lld frames (VAE, %s, prototype)", prefix.c_str(), static_cast<long long>(p.settings.frames),
      p.masks.empty() ? "no masks" : "masks");
  const EgoPressureDiffPipeline::Shared sh =
      pipe.encode(p.frames, p.masks.empty() ? nullptr : &p.masks, p.settings, &times);
  throw_if_interrupted("after encoding");
  say("%sdenoising: %s sampler, %d steps, seed %llu", prefix.c_str(), sh.sampler->name(), sh.sampler->num_steps(),
      static_cast<unsigned long long>(o.seed));
  const EgoPressureDiffPipeline::Result r = pipe.run(sh, text, p.settings, StepProgress(prefix), &times);
  throw_if_interrupted("after decoding");

  say("%swriting outputs", prefix.c_str());
  FrameForces ff;
  double total = 0;
  out.fill_and_commit([&](const std::string& dir) {
    {
      ScopedStage st(&times, "write");
      ff = write_outputs(dir, p, r);
    }
    ojson j = summary_json(o, src, p, sh, prompt, truncated, ff);
    total = seconds_since(p.start);
    finish_summary(j, dir, times, total);
  });
  ClipOutcome c;
  c.frames = int64_t(ff.total_n.size());
  c.mean_total_force_n = ff.mean();
  c.peak_total_force_n = ff.peak();
  c.seconds = total;
  return c;
}

int run_predict(const PredictOptions& o) {
  install_interrupt_handlers();
  check_predict_options(o);
  const ClipSource src = clip_source(o);
  const PredictModel model(o);
  const ClipOutcome c = predict_clip(model, o, src, o.out_dir);
  say("done in %.1f s: mean total force %.2f N, peak %.2f N%s", model.load_seconds() + c.seconds,
      c.mean_total_force_n, c.peak_total_force_n, model.builtin() ? " (synthetic model: not meaningful)" : "");
  say("outputs in %s: heatmap_000.png..heatmap_%03lld.png, side_by_side.mp4, taxels.csv, summary.json",
      o.out_dir.c_str(), static_cast<long long>(c.frames > 0 ? c.frames - 1 : 0));
  return 0;
}

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
      if (o.folder == v.folder) v.folder += "_" + std::to_string(out.size());
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

// Encodes the clip once, denoises once per variant and writes every variant folder, comparison.png and forces.csv
// into `root`; returns the closing summary line.
std::string counterfactual_into(const std::string& root, const PredictModel& model, const PredictOptions& o,
                                const ClipSource& src, const std::vector<Variant>& variants, const VarySpec& vary) {
  Prepared p = prepare_clip(model, o, src, root, "");
  EgoPressureDiffPipeline& pipe = p.pipe();

  say("encoding %lld frames once (VAE, %s, prototype, seed-%llu noise)", static_cast<long long>(p.settings.frames),
      p.masks.empty() ? "no masks" : "masks", static_cast<unsigned long long>(o.seed));
  const EgoPressureDiffPipeline::Shared sh =
      pipe.encode(p.frames, p.masks.empty() ? nullptr : &p.masks, p.settings, &p.times);
  const double shared_seconds = p.times.total();
  say("reusing the cached conditioning (RGB latents, mask features, prototype token, initial and step noises) for "
      "all %zu variants; only the prompt changes", variants.size());

  const int64_t F = sh.frames;
  const std::vector<int64_t> columns = uniform_frame_indices(F, std::min<int64_t>(4, F));
  std::vector<std::string> labels;
  std::vector<std::vector<cv::Mat>> cells;
  std::vector<FrameForces> forces;
  std::vector<double> variant_seconds;
  for (size_t k = 0; k < variants.size(); ++k) {
    const Variant& v = variants[k];
    const auto t0 = Clock::now();
    char prefix[64];
    std::snprintf(prefix, sizeof prefix, "[%zu/%zu] ", k + 1, variants.size());
    say("%s%s", prefix, v.label.c_str());
    StageTimes vt;
    const std::optional<std::string> prompt = pipe.prompt_for(v.fields);
    bool truncated = false;
    const Tensor text = pipe.encode_text(prompt, &truncated, &vt);
    announce_prompt(prompt, truncated, prefix);
    say("%sdenoising: %s sampler, %d steps", prefix, sh.sampler->name(), sh.sampler->num_steps());
    const EgoPressureDiffPipeline::Result r = pipe.run(sh, text, p.settings, StepProgress(prefix), &vt);
    const std::string dir = (fs::path(root) / v.folder).string();
    FrameForces ff;
    {
      ScopedStage st(&vt, "write");
      ff = write_outputs(dir, p, r);
    }
    std::vector<cv::Mat> row;
    for (int64_t c : columns) row.push_back(painted(pipe, r.frames[size_t(c)].h_std));
    cells.push_back(std::move(row));
    char force[64];
    std::snprintf(force, sizeof force, "mean %.2f N", ff.mean());
    labels.push_back(v.label);
    labels.push_back(force);
    const double secs = seconds_since(t0);
    ojson j = summary_json(o, src, p, sh, prompt, truncated, ff);
    j["variant"] = {{"field", vary.field}, {"value", v.value}};
    j["shared_timings_s"] = timings_json(p.times, shared_seconds);
    finish_summary(j, dir, vt, secs);
    std::string stages;
    for (const auto& [name, s] : vt.entries()) {
      char b[64];
      std::snprintf(b, sizeof b, "%s%s %.2f s", stages.empty() ? "" : ", ", name.c_str(), s);
      stages += b;
    }
    say("%s%s: %.2f s (%s)", prefix, v.folder.c_str(), secs, stages.c_str());
    forces.push_back(ff);
    variant_seconds.push_back(secs);
  }

  write_png_atomic((fs::path(root) / "comparison.png").string(), comparison_figure(labels, cells, columns));
  std::string csv = "variant,field,value,mean_total_force_n,peak_total_force_n,contact_frames,seconds\n";
  std::printf("%-28s %-16s %12s %12s %8s %9s\n", "variant", "value", "mean_N", "peak_N", "contact", "seconds");
  for (size_t k = 0; k < variants.size(); ++k) {
    const FrameForces& ff = forces[k];
    const long contact = long(std::count(ff.contact.begin(), ff.contact.end(), true));
    std::string quoted = "\"";  // the value is free text (materials, names): CSV-quote it
    for (char c : variants[k].value) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    quoted += "\"";
    char nums[160];
    std::snprintf(nums, sizeof nums, ",%.6g,%.6g,%ld,%.3f\n", ff.mean(), ff.peak(), contact, variant_seconds[k]);
    csv += variants[k].folder + "," + vary.field + "," + quoted + nums;
    std::printf("%-28s %-16s %12.3f %12.3f %5ld/%-2lld %9.2f\n", variants[k].folder.c_str(),
                variants[k].value.c_str(), ff.mean(), ff.peak(), contact, static_cast<long long>(F),
                variant_seconds[k]);
  }
  std::fflush(stdout);
  write_file_atomic((fs::path(root) / "forces.csv").string(), csv);
  double per_variant = 0;
  for (double s : variant_seconds) per_variant += s;
  char line[256];
  std::snprintf(line, sizeof line, "done in %.1f s: loading + encoding %.2f s once, %zu variants %.2f s (%.2f s each)",
                model.load_seconds() + seconds_since(p.start), shared_seconds, variants.size(), per_variant,
                per_variant / double(variants.size()));
  return line;
}

}  // namespace

int run_counterfactual(const PredictOptions& o, const VarySpec& vary) {
  if (o.prompt) throw Error("counterfactual varies prompt fields: give --meta (or nothing), not --prompt");
  if (vary.values.empty()) throw Error("--vary needs at least one value");
  install_interrupt_handlers();
  check_predict_options(o);
  const ClipSource src = clip_source(o);
  const PromptFields base = src.meta ? *src.meta : PromptFields{};
  const std::vector<Variant> variants = make_variants(base, vary);
  const PredictModel model(o);
  AtomicDir out(o.out_dir, "forces.csv");  // every variant, the figure and forces.csv appear together or not at all
  std::string done;
  out.fill_and_commit([&](const std::string& dir) { done = counterfactual_into(dir, model, o, src, variants, vary); });
  say("%s", done.c_str());
  say("outputs in %s: one folder per variant (%s, ...), comparison.png, forces.csv%s", o.out_dir.c_str(),
      variants[0].folder.c_str(), model.builtin() ? " (synthetic model: forces not meaningful)" : "");
  return 0;
}

}  // namespace egopd
