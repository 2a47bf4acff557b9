#include "batch/split_evaluation.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/json_text.h"
#include "pipeline/media.h"
#include "pressure/normalization.h"
#include "pressure/renderer.h"

namespace egopd {
namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

namespace {

// What a prediction folder says about its frames: S and the source frame of each predicted frame.
struct PredictionInfo {
  int size = 0;
  std::vector<int64_t> source_index;
  std::string template_name;
};

PredictionInfo read_summary(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error(path + ": cannot open (is the prediction folder complete?)");
  nlohmann::json j;
  try {
    j = parse_json(in);
    PredictionInfo info;
    info.size = j.at("size").get<int>();
    info.template_name = j.at("template").at("name").get<std::string>();
    for (const auto& f : j.at("per_frame")) info.source_index.push_back(f.at("source_index").get<int64_t>());
    if (info.size < 1 || info.source_index.empty()) throw Error(path + ": no frames or no size");
    return info;
  } catch (const nlohmann::json::exception&) {
    throw Error(path + ": not a summary.json written by egopd predict (size, template, per_frame.source_index)");
  }
}

// H_raw of a ground-truth heatmap image: grey value / maximum (channel mean for colour), squashed to S x S.
std::vector<double> heatmap_raw(const std::string& path, int size) {
  const cv::Mat img = cv::imread(path, cv::IMREAD_UNCHANGED);
  if (img.empty()) throw Error(path + ": cannot decode ground-truth heatmap");
  if (img.depth() != CV_8U && img.depth() != CV_16U) throw Error(path + ": heatmap must be 8- or 16-bit");
  const double full = img.depth() == CV_8U ? 255.0 : 65535.0;
  cv::Mat grey;
  img.convertTo(grey, CV_64F, 1.0 / full);
  if (grey.channels() == 4) cv::cvtColor(grey, grey, cv::COLOR_BGRA2BGR);
  if (grey.channels() == 3) {
    std::vector<cv::Mat> ch;
    cv::split(grey, ch);
    grey = (ch[0] + ch[1] + ch[2]) / 3.0;
  }
  const cv::Mat sq = squash_to_square(grey, size);
  std::vector<double> h(size_t(size) * size);
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) h[size_t(y) * size + x] = std::clamp(sq.at<double>(y, x), 0.0, 1.0);
  return h;
}

std::vector<std::string> pressure_images(const std::string& dir) {
  const std::vector<std::string> out = files_with_stem_suffix(list_image_files(dir), "_pressure");
  if (out.empty()) throw Error(dir + ": no *_pressure images (ground-truth heatmaps)");
  return out;
}

// Ground truth (stabilised, normalised) for each predicted frame, numbered 0..F-1 like taxels.csv.
class GroundTruthReader {
 public:
  explicit GroundTruthReader(const HandTemplate& t) : t_(t) {}

  TaxelSequence read(const std::string& gt, const PredictionInfo& info) {
    TaxelSequence raw;
    raw.num_taxels = t_.num_sensors();
    if (fs::is_directory(gt)) {
      const std::vector<std::string> files = pressure_images(gt);
      const PressureRenderer& r = renderer(info.size);
      std::vector<double> newtons(size_t(raw.num_taxels));
      for (size_t f = 0; f < info.source_index.size(); ++f) {
        const int64_t s = info.source_index[f];
        if (s < 0 || s >= int64_t(files.size()))
          throw Error(gt + ": no ground-truth heatmap for frame " + std::to_string(s) + " (" +
                      std::to_string(files.size()) + " *_pressure images)");
        const std::vector<double> p = r.readout(r.percentile_floor(heatmap_raw(files[size_t(s)], info.size)));
        for (int m = 0; m < raw.num_taxels; ++m) newtons[size_t(m)] = kPressureMax * p[size_t(m)];
        raw.add_row(int64_t(f), newtons.data());
      }
    } else {
      const TaxelSequence csv = read_taxel_csv(gt);
      if (csv.num_taxels != t_.num_sensors())
        throw Error(gt + ": " + std::to_string(csv.num_taxels) + " taxel columns, but the hand template has " +
                    std::to_string(t_.num_sensors()));
      std::map<int64_t, int64_t> row_of;
      for (int64_t i = 0; i < csv.num_frames(); ++i) row_of[csv.frames[size_t(i)]] = i;
      for (size_t f = 0; f < info.source_index.size(); ++f) {
        const auto it = row_of.find(info.source_index[f]);
        if (it == row_of.end())
          throw Error(gt + ": no row for frame " + std::to_string(info.source_index[f]) + " (a predicted frame)");
        raw.add_row(int64_t(f), csv.row(it->second));
      }
    }
    return ground_truth_from_newtons(t_, raw);
  }

 private:
  const PressureRenderer& renderer(int size) {
    auto& r = renderers_[size];
    if (!r) r = std::make_unique<PressureRenderer>(t_, size);
    return *r;
  }
  const HandTemplate& t_;
  std::map<int, std::unique_ptr<PressureRenderer>> renderers_;
};

std::string first_line(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  return line.empty() ? "failed (no message)" : line;
}

std::string cell(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

const char* status_name(ClipResult::Status s) {
  switch (s) {
    case ClipResult::Status::kEvaluated: return "evaluated";
    case ClipResult::Status::kMissing: return "missing";
    case ClipResult::Status::kFailed: return "failed";
    case ClipResult::Status::kNoGroundTruth: return "no_ground_truth";
  }
  return "?";
}

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? sep : "") + v[i];
  return s;
}

}  // namespace

bool ManifestEvaluation::complete() const {
  for (const ClipResult& c : clips)
    if (c.status == ClipResult::Status::kMissing || c.status == ClipResult::Status::kFailed) return false;
  return true;
}

ManifestEvaluation evaluate_manifest(const Manifest& m, const std::string& pred_dir, const std::string& run,
                                     const HandTemplate& t, const EvaluationOptions& opt) {
  if (!fs::is_directory(pred_dir)) throw Error(pred_dir + ": prediction folder does not exist");
  ManifestEvaluation e;
  e.run = run;
  GroundTruthReader gt_reader(t);
  std::vector<std::string> split_names;
  std::map<std::string, MetricAccumulator> pooled;
  pooled.emplace("all", MetricAccumulator(t));
  for (const ManifestClip& mc : m.clips) {
    ClipResult c;
    c.id = mc.id;
    c.splits = mc.splits;
    for (const std::string& s : mc.splits)
      if (pooled.emplace(s, MetricAccumulator(t)).second) split_names.push_back(s);
    const fs::path dir = fs::path(pred_dir) / mc.id;
    const std::string failed = (fs::path(pred_dir) / (mc.id + ".failed")).string();
    if (!fs::is_directory(dir)) {
      c.status = fs::exists(failed) ? ClipResult::Status::kFailed : ClipResult::Status::kMissing;
      if (c.status == ClipResult::Status::kFailed) c.detail = first_line(failed);
    } else if (mc.gt.empty()) {
      c.status = ClipResult::Status::kNoGroundTruth;
    } else {
      const PredictionInfo info = read_summary((dir / "summary.json").string());
      if (info.template_name != t.name())
        throw Error((dir / "summary.json").string() + ": predicted with hand template '" + info.template_name +
                    "', evaluated with '" + t.name() + "' (pass the same --template)");
      const TaxelSequence gt = gt_reader.read(mc.gt, info);
      const std::string pred_path = (dir / "taxels.csv").string();
      const TaxelSequence pred = predictions_from_newtons(t, read_taxel_csv(pred_path), opt.stabilize_predictions);
      if (pred.num_frames() != gt.num_frames() || pred.frames != gt.frames)
        throw Error(pred_path + ": frames 0.." + std::to_string(gt.num_frames() - 1) +
                    " expected (one row per frame of summary.json)");
      MetricAccumulator acc(t);
      acc.add(gt, pred);
      c.metrics = acc.result();
      c.status = ClipResult::Status::kEvaluated;
      c.detail = fs::is_directory(mc.gt) ? "heatmaps" : "taxel CSV";
      pooled.at("all").merge(acc);
      for (const std::string& s : mc.splits) pooled.at(s).merge(acc);
    }
    e.clips.push_back(std::move(c));
  }
  split_names.push_back("all");
  for (const std::string& name : split_names) {
    SplitResult s;
    s.name = name;
    for (const ClipResult& c : e.clips) {
      if (name != "all" && std::find(c.splits.begin(), c.splits.end(), name) == c.splits.end()) continue;
      ++s.clips;
      if (c.status == ClipResult::Status::kEvaluated) ++s.evaluated;
      if (c.status == ClipResult::Status::kMissing) s.missing.push_back(c.id);
      if (c.status == ClipResult::Status::kFailed) s.failed.push_back(c.id);
      if (c.status == ClipResult::Status::kNoGroundTruth) s.no_ground_truth.push_back(c.id);
    }
    s.pooled = pooled.at(name).result();
    e.splits.push_back(std::move(s));
  }
  return e;
}

ojson manifest_evaluation_json(const ManifestEvaluation& e, const HandTemplate& t, const EvaluationOptions& opt) {
  ojson j;
  j["run"] = e.run;
  j["complete"] = e.complete();
  j["splits"] = ojson::object();
  for (const SplitResult& s : e.splits) {
    ojson sj;
    put_metrics_json(sj, s.pooled);
    sj["clips"] = s.clips;
    sj["clips_evaluated"] = s.evaluated;
    sj["missing"] = s.missing;
    sj["failed"] = s.failed;
    sj["no_ground_truth"] = s.no_ground_truth;
    j["splits"][s.name] = sj;
  }
  j["clips"] = ojson::array();
  for (const ClipResult& c : e.clips) {
    ojson cj;
    cj["id"] = c.id;
    cj["splits"] = c.splits;
    cj["status"] = status_name(c.status);
    if (c.status == ClipResult::Status::kEvaluated) put_metrics_json(cj, c.metrics);
    if (!c.detail.empty()) cj[c.status == ClipResult::Status::kFailed ? "error" : "ground_truth"] = c.detail;
    j["clips"].push_back(cj);
  }
  j["template"] = {{"name", t.name()}, {"file", t.source()}, {"synthetic", t.synthetic()}};
  j["stabilize_predictions"] = opt.stabilize_predictions;
  return j;
}

std::string manifest_evaluation_markdown(const ManifestEvaluation& e, const HandTemplate& t) {
  std::string head = "| Run |", rule = "|---|", row = "| " + e.run + " |";
  for (const SplitResult& s : e.splits) {
    for (const char* col : {"Temp Acc (%)", "C-IoU (%)", "V-IoU (%)", "MAE (N)", "CoP"}) {
      head += " " + s.name + " " + col + " |";
      rule += "---|";
    }
    const PressureMetrics& m = s.pooled;
    row += " " + cell(m.temporal_accuracy_pct, 1) + " | " + cell(m.contact_iou_pct, 1) + " | " +
           cell(m.volumetric_iou_pct, 1) + " | " + cell(m.mae_newton, 2) + " | " + cell(m.cop_error_grid, 2) + " |";
  }
  std::string md = head + "\n" + rule + "\n" + row + "\n\n";
  for (const SplitResult& s : e.splits) {
    md += "- " + s.name + ": " + std::to_string(s.evaluated) + " of " + std::to_string(s.clips) + " clips evaluated, " +
          std::to_string(s.pooled.frames) + " frames";
    if (!s.missing.empty()) md += "; MISSING: " + join(s.missing, ", ");
    if (!s.failed.empty()) md += "; FAILED: " + join(s.failed, ", ");
    if (!s.no_ground_truth.empty()) md += "; no ground truth: " + join(s.no_ground_truth, ", ");
    md += "\n";
  }
  md += "\nMetrics pooled over every frame of every clip of a split (sums, not means of clips). Ground truth "
        "stabilised and normalised; heatmap ground truth read out with the predictions' template and operator.";
  if (t.synthetic()) md += " Template '" + t.name() + "' is SYNTHETIC: CoP errors are in its own grid units.";
  return md + "\n";
}

std::string manifest_evaluation_csv(const ManifestEvaluation& e) {
  const auto num = [](double v) { return std::isfinite(v) ? cell(v, 6) : std::string(); };
  const auto quoted = [](const std::string& s) {
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  std::string csv =
      "id,splits,status,frames,temporal_accuracy_pct,contact_iou_pct,volumetric_iou_pct,mae_newton,cop_error_grid,"
      "detail\n";
  for (const ClipResult& c : e.clips) {
    const bool ok = c.status == ClipResult::Status::kEvaluated;
    const PressureMetrics& m = c.metrics;
    csv += c.id + "," + join(c.splits, ";") + "," + status_name(c.status) + "," +
           (ok ? std::to_string(m.frames) : "") + "," + (ok ? num(m.temporal_accuracy_pct) : "") + "," +
           (ok ? num(m.contact_iou_pct) : "") + "," + (ok ? num(m.volumetric_iou_pct) : "") + "," +
           (ok ? num(m.mae_newton) : "") + "," + (ok ? num(m.cop_error_grid) : "") + "," + quoted(c.detail) + "\n";
  }
  return csv;
}

}  // namespace egopd
