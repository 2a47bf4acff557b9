// `egopd evaluate --pred P --gt G [--template FILE] [--json FILE] [--stabilize-predictions]`: the five pressure
// metrics of one clip or of a split (directories matched by file name, sums pooled over every frame).
#include <cmath>
#include <cstdio>
#include <string>

#include "core/atomic_file.h"
#include "cli/commands.h"
#include "core/error.h"
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

}  // namespace

int cmd_evaluate(const Args& a) {
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

  if (!json_path.empty()) write_file_atomic(json_path, evaluation_json(r, t, opt).dump(2) + "\n");
  return 0;
}

}  // namespace egopd
