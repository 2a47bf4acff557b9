// `egopd predict` and `egopd counterfactual` as users of the C API (include/egopd.h): the options go into its
// structs, its log and progress callbacks print what the commands show on stderr, and its status becomes the exit
// status (130/143 after SIGINT/SIGTERM).
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cli/predict_options.h"
#include "core/block_pool.h"
#include "core/json_text.h"
#include "core/kernels/conv.h"
#include "core/kernels/gemm.h"
#include "core/threading.h"
#include "egopd.h"

namespace egopd {
namespace {

void log_line(void*, const char* line) {
  std::fprintf(stderr, "%s\n", line);
  std::fflush(stderr);
}

int show_progress(void* user, const egopd_progress* p) {
  RunProgress r;
  r.stage = p->stage;
  r.step = p->step, r.steps = p->steps;
  r.step_seconds = p->step_seconds, r.elapsed_seconds = p->elapsed_seconds;
  r.variant = p->variant, r.variants = p->variants;
  (*static_cast<StderrProgress*>(user))(r);
  return 0;
}

int failed(egopd_status st) {
  std::fprintf(stderr, "egopd: %s\n", egopd_last_error());
  return st == EGOPD_INTERRUPTED ? 128 + egopd_pending_signal() : 1;
}

const char* c_str_or_null(const std::string& s) { return s.empty() ? nullptr : s.c_str(); }

struct ModelHandle {
  egopd_model* m = nullptr;
  ~ModelHandle() { egopd_model_free(m); }
};
struct ResultHandles {
  std::vector<egopd_result*> r;
  ~ResultHandles() {
    for (egopd_result* x : r) egopd_result_free(x);
  }
};

// The force table of a counterfactual run on stdout: one row per variant.
void print_table(const std::vector<egopd_result*>& results) {
  std::printf("%-28s %-16s %12s %12s %8s %9s\n", "variant", "value", "mean_N", "peak_N", "contact", "seconds");
  for (const egopd_result* r : results) {
    const int64_t F = egopd_result_frames(r);
    long long contact = 0;
    for (int64_t f = 0; f < F; ++f) contact += egopd_result_contact(r)[f] != 0;
    std::printf("%-28s %-16s %12.3f %12.3f %5lld/%-2lld %9.2f\n", egopd_result_variant_folder(r),
                egopd_result_variant_value(r), egopd_result_mean_force(r), egopd_result_peak_force(r), contact,
                static_cast<long long>(F), egopd_result_seconds(r));
  }
  std::fflush(stdout);
}

}  // namespace

int run_with_library(const PredictOptions& o, const VarySpec* vary) {
  // Before any work (the model is not loaded for a mistyped path or a broken --meta file): the options are
  // checked and --meta is read here, once (its warnings printed once), and passed on as fields.
  check_predict_options(o);
  const ClipSource src = clip_source(o);
  const std::string meta_json = src.meta ? dump_json(nlohmann::json(*src.meta)) : "";
  egopd_install_signal_handlers();
  egopd_load_options lo;
  egopd_load_options_init(&lo);
  lo.threads = num_threads();
  lo.precision = precision_name(precision());  // --precision
  lo.conv = conv_algo_name(conv_algo());       // --conv (or EGOPD_CONV)
  lo.block_cache_mb = int64_t(block_cache_limit() >> 20);  // --block-cache-mb (or EGOPD_BLOCK_CACHE_MB)
  lo.low_mem = o.low_mem ? 1 : 0;
  lo.size = o.size;
  lo.template_path = c_str_or_null(o.template_path);
  lo.log = log_line;
  ModelHandle model;
  if (egopd_status st = egopd_model_load(c_str_or_null(o.model_dir), &lo, &model.m)) return failed(st);

  StderrProgress bar("");
  egopd_predict_options po;
  egopd_predict_options_init(&po);
  po.video = c_str_or_null(o.video);
  po.masks_dir = c_str_or_null(o.masks_dir);
  po.prompt = o.prompt ? o.prompt->c_str() : nullptr;
  po.meta_json = src.meta ? meta_json.c_str() : nullptr;
  po.sampler = c_str_or_null(o.sampler);
  po.steps = o.steps;
  po.seed = o.seed;
  po.num_frames = o.frames;
  po.size = o.size;
  if (o.guidance) po.has_guidance = 1, po.guidance_min = o.guidance->first, po.guidance_max = o.guidance->second;
  po.decode_chunk = o.decode_chunk;
  po.out_dir = o.out_dir.c_str();
  po.progress = show_progress;
  po.progress_user = &bar;

  ResultHandles results;
  if (!vary) {
    results.r.assign(1, nullptr);
    if (egopd_status st = egopd_predict(model.m, &po, &results.r[0])) return failed(st);
    return 0;
  }
  std::vector<const char*> values;
  for (const std::string& v : vary->values) values.push_back(v.c_str());
  results.r.assign(values.size(), nullptr);
  if (egopd_status st = egopd_counterfactual(model.m, &po, vary->field.c_str(), values.data(), values.size(),
                                             results.r.data()))
    return failed(st);
  print_table(results.r);
  return 0;
}

}  // namespace egopd
