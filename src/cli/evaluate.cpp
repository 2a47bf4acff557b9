// `egopd evaluate --pred P --gt G [--template FILE] [--json FILE] [--stabilize-predictions]`: the five pressure
// metrics of one clip or of a split (directories matched by file name, sums pooled over every frame).
#include <cmath>
#include <cstdio>
#include <string>

#include <filesystem>

#include "batch/split_evaluation.h"
#include "cli/commands.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "pressure/evaluation.h"

namespace egopd {
namespace {

std::string cell(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

void print_row(const std::string& name, const PressureMetrics& m) {
  std::printf("%-28s %7lld %10s %8s %8s %9s %9s\n", name.c_str(), static_cast<long long>(m.frames),
              cell(m.temporal_accuracy_pct, 2).c_str(), cell(m.contact_iou_pct, 2).c_str(),
              cell(m.volumetric_iou_pct, 2).c_str(), cell(m.mae_newton, 3).c_str(), cell(m.cop_error_grid, 3).c_str());
}

// --manifest: a batch run's folder against the manifest's ground truth, per split.
int evaluate_manifest_run(const Args& a) {
  const Manifest m = read_manifest(a.require("manifest"));
  const std::string pred = a.require("pred");
  std::string run = a.get("name", "");
  if (run.empty()) run = std::filesystem::path(pred).lexically_normal().filename().string();
  if (run.empty() || run == ".") run = "egopd";
  const std::string template_path = a.get("template", "");
  const std::string json_path = a.get("json", ""), md_path = a.get("markdown", ""), csv_path = a.get("csv", "");
  EvaluationOptions opt;
  opt.stabilize_predictions = a.flag("stabilize-predictions");
  a.finish();
  const HandTemplate t = HandTemplate::load(template_path.empty() ? default_template_path() : template_path);
  const ManifestEvaluation e = evaluate_manifest(m, pred, run, t, opt);
  const std::string md = manifest_evaluation_markdown(e, t);
  std::printf("%s", md.c_str());
  if (!json_path.empty()) write_file_atomic(json_path, dump_json(manifest_evaluation_json(e, t, opt), 2) + "\n");
  if (!md_path.empty()) write_file_atomic(md_path, md);
  if (!csv_path.empty()) write_file_atomic(csv_path, manifest_evaluation_csv(e));
  if (!e.complete()) {
    const SplitResult& all = e.splits.back();
    std::fprintf(stderr, "egopd: evaluate: %zu of %lld clips missing and %zu failed (%s): the tables cover %lld clips\n",
                 all.missing.size(), static_cast<long long>(all.clips), all.failed.size(),
                 (all.missing.empty() ? all.failed[0] : all.missing[0]).c_str(),
                 static_cast<long long>(all.evaluated));
    return 1;
  }
  return 0;
}

}  // namespace

int cmd_evaluate(const Args& a) {
  if (a.has("manifest")) return evaluate_manifest_run(a);
  const std::string pred = a.require("pred");
  const std::string gt = a.require("gt");
  const std::string template_path = a.get("template", "");
  const std::string json_path = a.get("json", "");
  EvaluationOptions opt;
  opt.stabilize_predictions = a.flag("stabilize-predictions");
  a.finish();

  const HandTemplate t = HandTemplate::load(template_path.empty() ? default_template_path() : template_path);
  const EvaluationReport r = evaluate_taxel_files(pred, gt, t, opt);

  std::printf("template: %s (%s)%s\n", t.name().c_str(), t.source().c_str(),
              t.synthetic() ? " - SYNTHETIC layout, not the real glove: CoP errors are in its own grid units" : "");
  std::printf("ground truth: stabilised + normalised (p_min 5 N, p_max 200 N, contact p > 0.025); predictions: "
              "N / 200%s\n\n",
              opt.stabilize_predictions ? ", stabilised" : "");
  std::printf("%-28s %7s %10s %8s %8s %9s %9s\n", "clip", "frames", "temp_acc%", "c_iou%", "v_iou%", "mae_N",
              "cop_grid");
  if (r.clips.size() > 1)
    for (const auto& c : r.clips) print_row(c.name, c.metrics);
  print_row(r.clips.size() > 1 ? "pooled (split)" : r.clips[0].name, r.pooled);

  if (!json_path.empty()) write_file_atomic(json_path, dump_json(evaluation_json(r, t, opt), 2) + "\n");
  return 0;
}

}  // namespace egopd
