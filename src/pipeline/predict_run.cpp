#include "pipeline/predict_run.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstring>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <system_error>

#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/json_text.h"
#include "core/kernels/gemm.h"
#include "core/utf8.h"
#include "pressure/hand_template.h"
#include "core/memory.h"
#include "core/safetensors.h"
#include "core/timing.h"
#include "pipeline/egopressurediff.h"
#include "pipeline/media.h"
#include "pipeline/predict_detail.h"
#include "pipeline/synthetic_model.h"
#include "pressure/pressure.h"
#include "pressure/taxel_csv.h"
#include "scheduler/sampler.h"

namespace egopd {
namespace fs = std::filesystem;
using namespace detail;

namespace {

// The built-in demo model: the "tiny" preset as a 4-step AnimateLCM student, so the demo stays within seconds.
// The cache folder is named by these parameters and synthetic_model_id, so a change here, in the model classes or in
// the generator never reuses a stale directory.
constexpr uint64_t kBuiltinSeed = 0;
constexpr int kBuiltinLcmSteps = 4;
constexpr DType kBuiltinDType = DType::F32;
constexpr const char* kBuiltinName = "tiny-synthetic-f32-lcm4-seed0";

void require_exists(const std::string& path, const std::string& what) {
  if (!path.empty() && !fs::exists(path)) throw Error(path + ": " + what + " does not exist");
}

std::string model_scheduler_name(const std::string& model_dir) {
  const fs::path cfg = fs::path(model_dir) / "scheduler";
  if (!fs::is_directory(cfg)) return "";  // the pipeline reports the missing part
  return load_sampler(cfg.string())->name();
}

std::string where_of(const RunProgress& p) {
  std::string w = std::string("at ") + p.stage;
  if (p.steps > 0) w += " step " + std::to_string(p.step) + " of " + std::to_string(p.steps);
  if (p.variants > 0) w += " of variant " + std::to_string(p.variant) + " of " + std::to_string(p.variants);
  return w;
}

}  // namespace

Cancelled::Cancelled(const std::string& where)
    : Error("cancelled by the progress callback " + where + ": stopped, no partial output left") {}

StderrProgress::StderrProgress(std::string prefix) : prefix_(std::move(prefix)), tty_(::isatty(2) != 0) {}

void StderrProgress::operator()(const RunProgress& p) {
  std::string prefix = prefix_;
  if (p.variants > 0) prefix += "[" + std::to_string(p.variant) + "/" + std::to_string(p.variants) + "] ";
  if (std::strcmp(p.stage, "decode") == 0) {
    std::fprintf(stderr, "%sdecoding %s\n", prefix.c_str(), "(temporal VAE) and reading out taxels");
  } else if (std::strcmp(p.stage, "denoise") == 0 && p.step > 0) {
    const int i = p.step, n = p.steps;
    if (i == 1) sum_ = 0;
    sum_ += p.step_seconds;
    const double per = sum_ / i, eta = per * (n - i);
    if (tty_) {
      constexpr int kWidth = 24;
      const int fill = int(std::lround(double(kWidth) * i / n));
      const std::string bar = std::string(size_t(fill), '#') + std::string(size_t(kWidth - fill), ' ');
      const long e = std::lround(eta);
      std::fprintf(stderr, "\r%sstep %d/%d [%s] %.2f s/it ETA %ld:%02ld\033[K", prefix.c_str(), i, n, bar.c_str(),
                   per, e / 60, e % 60);
      if (i == n) std::fputc('\n', stderr);
    } else {
      std::fprintf(stderr, "%sstep %d/%d %.2f s/it ETA %.0f s\n", prefix.c_str(), i, n, per, eta);
    }
  }
  std::fflush(stderr);
}

RunHooks stderr_hooks(const std::string& prefix) {
  RunHooks h;
  h.log = [](const std::string& line) {
    std::fprintf(stderr, "%s\n", line.c_str());
    std::fflush(stderr);
  };
  auto bar = std::make_shared<StderrProgress>(prefix);
  h.progress = [bar](const RunProgress& p) {
    (*bar)(p);
    return true;
  };
  h.prefix = prefix;
  return h;
}

namespace detail {

void Reporter::say(const char* fmt, ...) const {
  if (!hooks_.log) return;
  va_list ap;
  va_start(ap, fmt);
  char buf[1024];
  const int n = std::vsnprintf(buf, sizeof buf, fmt, ap);
  va_end(ap);
  std::string line = buf;
  if (n >= int(sizeof buf)) {  // long paths or prompts: format again into a buffer of the right size
    std::vector<char> big(size_t(n) + 1);
    va_start(ap, fmt);
    std::vsnprintf(big.data(), big.size(), fmt, ap);
    va_end(ap);
    line = big.data();
  }
  hooks_.log(line);
}

void Reporter::report(RunProgress p, const std::string& where) const {
  p.elapsed_seconds = seconds_since(start_);
  p.variant = variant_, p.variants = variants_;
  if (hooks_.progress && !hooks_.progress(p)) throw Cancelled(where.empty() ? where_of(p) : where);
}

void Reporter::stage(const char* name) const {
  RunProgress p;
  p.stage = name;
  report(p, "");
}

void Reporter::step(int i, int n, double seconds) const {
  RunProgress p;
  p.stage = "denoise";
  p.step = i, p.steps = n, p.step_seconds = seconds;
  report(p, "");
  throw_if_interrupted("after step " + std::to_string(i) + " of " + std::to_string(n));
  if (i == n) stage("decode");
}

}  // namespace detail

void check_predict_options(const PredictOptions& o) {
  if (o.size < 64 || o.size % 64) throw Error("--size must be a positive multiple of 64 (got " + std::to_string(o.size) + ")");
  if (o.prompt && !o.meta_path.empty()) throw Error("give either --prompt or --meta, not both");
  if (o.steps < 0) throw Error("--steps must be positive");
  if (o.frames < 0) throw Error("--frames must be at least 1");
  if (o.decode_chunk < 0) throw Error("--decode-chunk must be positive");
  if (!o.sampler.empty() && o.sampler != "euler" && o.sampler != "lcm")
    throw Error("--sampler must be euler or lcm (got '" + o.sampler + "')");
  if (o.guidance && (!std::isfinite(o.guidance->first) || !std::isfinite(o.guidance->second) ||
                     o.guidance->first < 0 || o.guidance->second < 0))
    throw Error("--guidance: MIN and MAX must be finite and not negative");
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

namespace detail {

Prepared prepare_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                      const std::string& work_dir, const Reporter& rep) {
  Prepared p;
  p.start = Clock::now();
  p.model = &model;
  if (!src.video.empty() && !src.frames.empty()) throw Error("give either a video (--video) or frames, not both");
  if (!src.masks_dir.empty() && !src.masks.empty()) throw Error("give either a mask folder (--masks) or masks, not both");
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

  const int S = int(p.pipe().size());
  const char* prefix = rep.prefix().c_str();
  p.builtin_clip = src.video.empty() && src.frames.empty();
  if (p.builtin_clip) {
    p.clip.rgb = synthetic_sample_clip(int(s.frames), S);
    p.clip.source_frames = s.frames;
    for (int64_t i = 0; i < s.frames; ++i) p.clip.source_indices.push_back(i);
    if (!work_dir.empty()) {
      std::vector<cv::Mat> bgr;
      for (const cv::Mat& m : p.clip.rgb) {
        cv::Mat b;
        cv::cvtColor(m, b, cv::COLOR_RGB2BGR);
        bgr.push_back(b);
      }
      write_video_atomic((fs::path(work_dir) / "sample_clip.mp4").string(), bgr, kVideoFps);
    }
    rep.say("%sclip: built-in SYNTHETIC sample clip (%lld frames%s)", prefix, static_cast<long long>(s.frames),
            work_dir.empty() ? "" : ", saved as sample_clip.mp4");
  } else if (!src.frames.empty()) {
    p.clip = clip_from_images(src.frames, s.frames, S);
    rep.say("%sclip: %zu frames from memory (%dx%d, %lld sampled)", prefix, src.frames.size(), src.frames[0].cols,
            src.frames[0].rows, static_cast<long long>(s.frames));
  } else {
    p.clip = load_clip(src.video, s.frames, S);
    rep.say("%sclip: %s (%lld frames, %lld sampled)", prefix, src.video.c_str(),
            static_cast<long long>(p.clip.source_frames), static_cast<long long>(s.frames));
  }
  p.frames = frames_to_tensor(p.clip.rgb);
  if (!src.masks_dir.empty()) p.masks = load_masks(src.masks_dir, p.clip, S);
  else if (!src.masks.empty()) p.masks = masks_from_images(src.masks, p.clip, S, "masks");
  return p;
}

ClipOutcome outcome_of(const Prepared& p, const EgoPressureDiffPipeline::Result& r) {
  ClipOutcome c;
  c.frames = int64_t(r.frames.size());
  c.size = p.pipe().size();
  c.num_taxels = r.frames.empty() ? 0 : int(r.frames[0].p.size());
  const size_t plane = size_t(c.size * c.size);
  for (const PressureRenderer::Frame& fr : r.frames) {
    if (int(fr.p.size()) != c.num_taxels || fr.h_std.size() != plane) throw Error("internal: frames of different sizes");
    double total = 0;
    bool contact = false;
    for (double v : fr.p) {
      const double n = kPressureMax * v;  // as newtons_from_normalized writes taxels.csv
      c.taxels_n.push_back(n);
      total += n, contact = contact || in_contact(v);
    }
    for (double h : fr.h_std) c.heatmaps.push_back(float(h));
    c.total_force_n.push_back(total);
    c.contact.push_back(contact ? 1 : 0);
  }
  for (double t : c.total_force_n) c.mean_total_force_n += t;
  if (c.frames > 0) c.mean_total_force_n /= double(c.frames);
  if (c.frames > 0) c.peak_total_force_n = *std::max_element(c.total_force_n.begin(), c.total_force_n.end());
  return c;
}

cv::Mat painted(const EgoPressureDiffPipeline& pipe, const std::vector<double>& h) {
  const int S = int(pipe.size());
  HeatmapPaintOptions opt;
  opt.order = ChannelOrder::BGR;
  std::vector<uint8_t> px = paint_heatmap(h, S, pipe.renderer().outline_canvas(), opt);
  return cv::Mat(S, S, CV_8UC3, px.data()).clone();
}

namespace {
std::string numbered(const char* stem, size_t i, const char* ext) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "%s_%03zu.%s", stem, i, ext);
  return buf;
}
}  // namespace

void write_outputs(const std::string& dir, const Prepared& p, const EgoPressureDiffPipeline::Result& r,
                   const ClipOutcome& c) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (!fs::is_directory(dir)) throw Error(dir + ": cannot create output folder");
  std::vector<cv::Mat> side;
  for (size_t f = 0; f < r.frames.size(); ++f) {
    cv::Mat heat = painted(p.pipe(), r.frames[f].h_std);
    write_png_atomic((fs::path(dir) / numbered("heatmap", f, "png")).string(), heat);
    cv::Mat rgb_bgr, pair;
    cv::cvtColor(p.clip.rgb[f], rgb_bgr, cv::COLOR_RGB2BGR);
    cv::hconcat(rgb_bgr, heat, pair);
    side.push_back(pair);
  }
  write_video_atomic((fs::path(dir) / "side_by_side.mp4").string(), side, kVideoFps);
  TaxelSequence seq;
  seq.num_taxels = c.num_taxels;
  for (int64_t f = 0; f < c.frames; ++f) seq.add_row(f, c.taxels_n.data() + f * c.num_taxels);
  write_taxel_csv((fs::path(dir) / "taxels.csv").string(), seq);
}

ojson timings_json(const StageTimes& t, double total) {
  ojson j = ojson::object();
  for (const auto& [k, v] : t.entries()) j[k] = v;
  j["total"] = total;
  return j;
}

ojson summary_json(const PredictOptions& o, const ClipSource& src, const Prepared& p,
                   const EgoPressureDiffPipeline::Shared& sh, const std::optional<std::string>& prompt, bool truncated,
                   const ClipOutcome& c) {
  ojson j;
  j["prompt"] = prompt ? ojson(*prompt) : ojson(nullptr);
  j["prompt_truncated"] = truncated;
  j["seed"] = o.seed;
  j["sampler"] = sh.sampler->name();
  j["steps"] = sh.sampler->num_steps();
  j["frames"] = sh.frames;
  j["size"] = p.pipe().size();
  j["guidance"] = {p.settings.min_guidance, p.settings.max_guidance};
  j["low_mem"] = p.pipe().low_mem();
  j["decode_chunk"] = o.decode_chunk > 0 ? o.decode_chunk : sh.frames;
  j["precision"] = precision_name(precision());  // of the linear layers and convolutions (--precision)
  j["model_dir"] = p.model->model_dir();
  j["model_synthetic"] = p.model->builtin();
  if (p.builtin_clip) j["video"] = "sample_clip.mp4 (built-in synthetic clip)";
  else if (!src.frames.empty()) j["video"] = std::to_string(src.frames.size()) + " frames from memory";
  else j["video"] = src.video;
  if (!src.masks.empty()) j["masks"] = std::to_string(src.masks.size()) + " masks from memory";
  else j["masks"] = src.masks_dir.empty() ? ojson(nullptr) : ojson(src.masks_dir);
  const HandTemplate& t = p.pipe().hand_template();
  j["template"] = {{"name", t.name()}, {"synthetic", t.synthetic()}};
  ojson frames = ojson::array();
  for (size_t f = 0; f < c.total_force_n.size(); ++f)
    frames.push_back({{"frame", f},
                      {"source_index", p.clip.source_indices[f]},
                      {"total_force_n", c.total_force_n[f]},
                      {"contact", c.contact[f] != 0}});
  j["mean_total_force_n"] = c.mean_total_force_n;
  j["peak_total_force_n"] = c.peak_total_force_n;
  j["per_frame"] = frames;
  return j;
}

void finish_summary(ojson& j, const std::string& dir, const StageTimes& times, double total, ClipOutcome& c) {
  j["timings_s"] = timings_json(times, total);
  j["peak_rss_bytes"] = peak_rss_bytes();
  c.summary_json = dump_json(j, 2) + "\n";
  c.seconds = total;
  if (!dir.empty()) write_file_atomic((fs::path(dir) / "summary.json").string(), c.summary_json);
}

void announce_prompt(const Reporter& rep, const std::optional<std::string>& prompt, bool truncated,
                     const std::string& prefix) {
  if (prompt) rep.say("%sprompt: \"%s\"", prefix.c_str(), prompt->c_str());
  else rep.say("%sno prompt: no-text mode", prefix.c_str());
  if (truncated) rep.say("%swarning: the prompt is longer than 77 CLIP tokens and was truncated", prefix.c_str());
}

}  // namespace detail

ClipSource clip_source(const PredictOptions& o) {
  ClipSource src{o.video, o.masks_dir, o.prompt, std::nullopt, {}, {}};
  if (!o.meta_path.empty()) src.meta = load_prompt_fields(o.meta_path);
  return src;
}

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

VarySpec make_vary(const std::string& field, std::vector<std::string> values) {
  VarySpec v;
  v.field = field;
  // The library's own field list decides which names are prompt attributes.
  if (field.empty() || !prompt_fields_from_json(nlohmann::json{{field, "x"}}, "--vary").count(field))
    throw Error("--vary: '" + field +
                "' is not a prompt field (obj_name, weight, material, gender, age, subj_weight, bodyfat)");
  if (values.empty()) throw Error("--vary needs at least one value");
  for (const std::string& value : values) {
    if (value.empty()) throw Error("--vary: empty value for '" + field + "'");
    if (!is_valid_utf8(value)) throw Error("--vary: a value for '" + field + "' is not valid UTF-8 text");
  }
  v.values = std::move(values);
  return v;
}

VarySpec parse_vary(const std::string& text) {
  const size_t eq = text.find('=');
  if (eq == std::string::npos || eq == 0 || eq + 1 == text.size())
    throw Error("--vary expects FIELD=v1,v2,... (e.g. weight=1,355,1000,omit), got '" + text + "'");
  std::vector<std::string> values;
  std::string rest = text.substr(eq + 1);
  size_t start = 0;
  while (start <= rest.size()) {
    const size_t c = std::min(rest.find(',', start), rest.size());
    const std::string item = rest.substr(start, c - start);
    if (item.empty()) throw Error("--vary: empty value in '" + text + "'");
    values.push_back(item);
    start = c + 1;
  }
  return make_vary(text.substr(0, eq), std::move(values));
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
  const std::string name = std::string(kBuiltinName) + "-" +
                           synthetic_model_id("tiny", kBuiltinSeed, kBuiltinDType, kBuiltinLcmSteps);
  if (!root.empty()) return (fs::path(root) / name).string();
  // Beside the output folder, not in it: the output folder is replaced as a whole by each run.
  const fs::path parent = fs::path(out_dir).lexically_normal().parent_path();
  return ((parent.empty() ? fs::path(".") : parent) / (".egopd-" + name)).string();
}

PredictModel::PredictModel(const PredictOptions& o, const RunHooks& hooks) {
  const auto start = Clock::now();
  const Reporter rep(hooks);
  check_predict_options(o);
  builtin_ = o.model_dir.empty();
  model_dir_ = builtin_ ? default_model_dir(o.out_dir) : o.model_dir;
  if (builtin_) {
    remove_abandoned_temporaries(model_dir_);  // left by a run killed while it wrote the model
    if (!fs::exists(fs::path(model_dir_) / "model_index.json")) {
      rep.say("creating the built-in synthetic model (tiny preset, random weights) in %s", model_dir_.c_str());
      // Built beside its place and moved in whole: parallel runs (batch array tasks) never see half a model; the
      // model is deterministic, so when another run got there first its copy is as good as ours.
      AtomicDir tmp(model_dir_, "model_index.json");
      write_synthetic_model(tmp.path(), "tiny", kBuiltinSeed, kBuiltinDType, kBuiltinLcmSteps);
      if (!fs::exists(fs::path(model_dir_) / "model_index.json")) tmp.commit();
    }
    rep.say("model: built-in SYNTHETIC model %s (random weights: the pressures are NOT meaningful)",
            model_dir_.c_str());
  }
  rep.say("loading model %s (%lldx%lld)", model_dir_.c_str(), static_cast<long long>(o.size),
          static_cast<long long>(o.size));
  if (o.low_mem) rep.say("low-memory mode: components are loaded one at a time and released after use");
  pipe_ = std::make_unique<EgoPressureDiffPipeline>(model_dir_, o.size, o.template_path, o.low_mem);
  const HandTemplate& t = pipe_->hand_template();
  rep.say("hand template: %s%s", t.name().c_str(), t.synthetic() ? " (SYNTHETIC layout, not the real glove)" : "");
  if (!pipe_->renderer().warnings().empty())
    rep.say("warning: %zu template sensors lie outside the hand region (first: %s)",
            pipe_->renderer().warnings().size(), pipe_->renderer().warnings()[0].c_str());
  load_seconds_ = seconds_since(start);
}

PredictModel::~PredictModel() = default;

ClipOutcome predict_clip(const PredictModel& model, const PredictOptions& o, const ClipSource& src,
                         const std::string& out_dir, const RunHooks& hooks) {
  const Reporter rep(hooks);
  const std::string& prefix = hooks.prefix;
  std::optional<AtomicDir> out;
  if (!out_dir.empty()) out.emplace(out_dir, "summary.json");
  Prepared p = prepare_clip(model, o, src, out ? out->path() : "", rep);
  EgoPressureDiffPipeline& pipe = p.pipe();
  StageTimes& times = p.times;
  const std::optional<std::string> prompt =
      src.prompt ? src.prompt : src.meta ? pipe.prompt_for(*src.meta) : std::nullopt;
  bool truncated = false;
  const Tensor text = pipe.encode_text(prompt, &truncated, &times);
  announce_prompt(rep, prompt, truncated, prefix);
  throw_if_interrupted("before encoding");

  rep.stage("encode");
  rep.say("%sencoding %lld frames (VAE, %s, prototype)", prefix.c_str(), static_cast<long long>(p.settings.frames),
          p.masks.empty() ? "no masks" : "masks");
  const EgoPressureDiffPipeline::Shared sh =
      pipe.encode(p.frames, p.masks.empty() ? nullptr : &p.masks, p.settings, &times);
  throw_if_interrupted("after encoding");
  rep.say("%sdenoising: %s sampler, %d steps, seed %llu", prefix.c_str(), sh.sampler->name(), sh.sampler->num_steps(),
          static_cast<unsigned long long>(o.seed));
  const EgoPressureDiffPipeline::Result r = pipe.run(sh, text, p.settings, rep.step_callback(), &times);
  throw_if_interrupted("after decoding");

  ClipOutcome c = outcome_of(p, r);
  if (!out) {
    ojson j = summary_json(o, src, p, sh, prompt, truncated, c);
    finish_summary(j, "", times, seconds_since(p.start), c);
    return c;
  }
  rep.stage("write");
  rep.say("%swriting outputs", prefix.c_str());
  out->fill_and_commit([&](const std::string& dir) {
    {
      ScopedStage st(&times, "write");
      write_outputs(dir, p, r, c);
    }
    ojson j = summary_json(o, src, p, sh, prompt, truncated, c);
    finish_summary(j, dir, times, seconds_since(p.start), c);
  });
  return c;
}

void log_predict_done(const RunHooks& hooks, const ClipOutcome& c, double load_seconds, bool builtin_model,
                      const std::string& out_dir) {
  const Reporter rep(hooks);
  rep.say("done in %.1f s: mean total force %.2f N, peak %.2f N%s", load_seconds + c.seconds, c.mean_total_force_n,
          c.peak_total_force_n, builtin_model ? " (synthetic model: not meaningful)" : "");
  if (!out_dir.empty())
    rep.say("outputs in %s: heatmap_000.png..heatmap_%03lld.png, side_by_side.mp4, taxels.csv, summary.json",
            out_dir.c_str(), static_cast<long long>(c.frames > 0 ? c.frames - 1 : 0));
}

int run_predict(const PredictOptions& o, const RunHooks& hooks) {
  if (o.out_dir.empty()) throw Error("--out is required");
  install_interrupt_handlers();
  check_predict_options(o);
  const ClipSource src = clip_source(o);
  const PredictModel model(o, hooks);
  const ClipOutcome c = predict_clip(model, o, src, o.out_dir, hooks);
  log_predict_done(hooks, c, model.load_seconds(), model.builtin(), o.out_dir);
  return 0;
}

}  // namespace egopd
