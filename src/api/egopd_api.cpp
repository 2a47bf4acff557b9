// The C API (include/egopd.h) over the prediction runs of predict_run.h: handles, option structs checked and
// converted, every exception turned into a status and a one-line message, one computing call at a time.
#include "egopd.h"

#include <algorithm>
#include <atomic>
#include <cstring>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "api/api_options.h"
#include "core/block_pool.h"
#include "core/error.h"
#include "core/interrupt.h"
#include "core/threading.h"
#include "egopd/version.h"
#include "pipeline/predict_run.h"

namespace egopd::api {
// Counts the models in existence. The block cache keeps freed activation blocks between calls (up to each model's
// block_cache_mb); when the last model goes, the cache is emptied, so a program that frees its models gets that
// memory back.
class ModelCount {
 public:
  ModelCount() { live_.fetch_add(1); }
  ~ModelCount() {
    if (live_.fetch_sub(1) == 1) empty_block_cache();
  }
  ModelCount(const ModelCount&) = delete;
  ModelCount& operator=(const ModelCount&) = delete;

 private:
  static inline std::atomic<int> live_{0};
};
}  // namespace egopd::api

struct egopd_model {
  egopd::api::ModelCount counted;  // first member, so destroyed last: after the model's tensors went to the cache
  egopd::PredictOptions load;  // model_dir as given ("": the built-in model), size, low_mem, template_path
  int threads = 0;
  egopd::Precision precision = egopd::Precision::Fp32;  // set for each of its calls, like threads
  egopd::ConvAlgo conv = egopd::ConvAlgo::Auto;          // likewise
  size_t block_cache_bytes = 0;                          // likewise
  egopd_log_fn log = nullptr;
  void* log_user = nullptr;
  std::unique_ptr<egopd::PredictModel> model;
  double unreported_load_seconds = 0;  // counted in the "done in" line of the next prediction
};

struct egopd_result {
  egopd::ClipOutcome c;
};

namespace egopd::api {
namespace {

thread_local std::string t_error;
thread_local bool t_in_call = false;  // inside a computing call on this thread (its callbacks included)
std::mutex g_compute;                 // one computing call at a time in the process

// Runs body; any exception becomes a status and the thread's last error.
template <class Body>
egopd_status guarded(Body&& body) {
  try {
    body();
    t_error.clear();
    return EGOPD_OK;
  } catch (const ArgumentError& e) {
    t_error = e.what();
    return EGOPD_ERROR_ARGUMENT;
  } catch (const Cancelled& e) {
    t_error = e.what();
    return EGOPD_CANCELLED;
  } catch (const Interrupted& e) {
    t_error = e.what();
    return EGOPD_INTERRUPTED;
  } catch (const std::bad_alloc&) {
    t_error = "out of memory";
    return EGOPD_ERROR_MEMORY;
  } catch (...) {
    try {
      t_error = current_exception_line();
    } catch (...) {  // no memory even for the message
      t_error.clear();
      return EGOPD_ERROR_MEMORY;
    }
    return EGOPD_ERROR;
  }
}

// A computing call: refused inside a callback of another one on this thread, then the process-wide lock and the
// model's thread count, compute precision and convolution algorithm.
class ComputeScope {
 public:
  explicit ComputeScope(const egopd_model& m) {
    if (t_in_call) throw ArgumentError("egopd_predict, egopd_counterfactual and egopd_model_load cannot be called from "
                                       "inside a progress or log callback");
    lock_ = std::unique_lock<std::mutex>(g_compute);
    t_in_call = true;
    set_num_threads(m.threads);
    set_precision(m.precision);
    set_conv_algo(m.conv);
    set_block_cache_limit(m.block_cache_bytes);
  }
  ~ComputeScope() { t_in_call = false; }
  ComputeScope(const ComputeScope&) = delete;
  ComputeScope& operator=(const ComputeScope&) = delete;

 private:
  std::unique_lock<std::mutex> lock_;
};

RunHooks model_hooks(const egopd_model& m) {
  RunHooks h;
  if (m.log) h.log = [log = m.log, user = m.log_user](const std::string& line) { log(user, line.c_str()); };
  return h;
}

RunHooks call_hooks(const egopd_model& m, const egopd_predict_options& o) {
  RunHooks h = model_hooks(m);
  if (o.progress)
    h.progress = [fn = o.progress, user = o.progress_user](const RunProgress& p) {
      egopd_progress c;
      std::memset(&c, 0, sizeof c);
      c.struct_size = sizeof c;
      c.stage = p.stage;
      c.step = p.step, c.steps = p.steps;
      c.step_seconds = p.step_seconds, c.elapsed_seconds = p.elapsed_seconds;
      c.variant = p.variant, c.variants = p.variants;
      return fn(user, &c) == 0;
    };
  return h;
}

egopd_model& model_of(egopd_model* m) {
  if (!m) throw ArgumentError("model: null handle (load one with egopd_model_load)");
  if (!m->model) throw ArgumentError("model: not loaded");
  return *m;
}

// The model prepared for the call's size (another size than the loaded one reloads it).
const PredictModel& model_for(egopd_model& m, int64_t size) {
  if (size != m.load.size) {
    PredictOptions o = m.load;
    o.size = size;
    m.model.reset();
    m.model = std::make_unique<PredictModel>(o, model_hooks(m));
    m.load.size = size;
    m.unreported_load_seconds += m.model->load_seconds();
  }
  return *m.model;
}

}  // namespace
}  // namespace egopd::api

using namespace egopd;
using namespace egopd::api;

extern "C" {

const char* egopd_version(void) { return EGOPD_VERSION; }

const char* egopd_last_error(void) { return t_error.c_str(); }

void egopd_install_signal_handlers(void) { install_interrupt_handlers(); }

int egopd_pending_signal(void) { return pending_interrupt(); }

void egopd_load_options_init(egopd_load_options* o) {
  if (!o) return;
  std::memset(o, 0, sizeof *o);
  o->struct_size = sizeof *o;
  o->size = 256;
  o->block_cache_mb = -1;
}

void egopd_predict_options_init(egopd_predict_options* o) {
  if (!o) return;
  std::memset(o, 0, sizeof *o);
  o->struct_size = sizeof *o;
}

egopd_status egopd_model_load(const char* model_dir, const egopd_load_options* options, egopd_model** model) {
  return guarded([&] {
    if (!model) throw ArgumentError("model: null pointer for the loaded model");
    *model = nullptr;
    const egopd_load_options o = read_load_options(options);
    auto m = std::make_unique<egopd_model>();
    m->load = load_predict_options(model_dir, o);
    m->threads = o.threads;
    m->precision = load_precision(o);
    m->conv = load_conv(o);
    m->block_cache_bytes = m->load.low_mem ? 0 : load_block_cache_bytes(o);
    m->log = o.log, m->log_user = o.log_user;
    ComputeScope scope(*m);
    m->model = std::make_unique<PredictModel>(m->load, model_hooks(*m));
    m->unreported_load_seconds = m->model->load_seconds();
    *model = m.release();
  });
}

void egopd_model_free(egopd_model* model) { delete model; }

const char* egopd_model_dir(const egopd_model* model) {
  return model && model->model ? model->model->model_dir().c_str() : "";
}

egopd_status egopd_predict(egopd_model* model, const egopd_predict_options* options, egopd_result** result) {
  return guarded([&] {
    if (!result) throw ArgumentError("result: null pointer for the result");
    *result = nullptr;
    egopd_model& m = model_of(model);
    const egopd_predict_options o = read_predict_options(options);
    const PredictOptions po = call_predict_options(m.load, o);
    const ClipSource src = call_clip_source(o, po, model_hooks(m));
    const RunHooks hooks = call_hooks(m, o);
    ComputeScope scope(m);
    const PredictModel& pm = model_for(m, po.size);
    auto r = std::make_unique<egopd_result>();
    r->c = predict_clip(pm, po, src, po.out_dir, hooks);
    log_predict_done(hooks, r->c, std::exchange(m.unreported_load_seconds, 0.0), pm.builtin(), po.out_dir);
    *result = r.release();
  });
}

egopd_status egopd_counterfactual(egopd_model* model, const egopd_predict_options* options, const char* field,
                                  const char* const* values, size_t num_values, egopd_result** results) {
  return guarded([&] {
    if (!results) throw ArgumentError("results: null pointer for the results array");
    for (size_t i = 0; i < num_values; ++i) results[i] = nullptr;
    egopd_model& m = model_of(model);
    const VarySpec vary = call_vary_spec(field, values, num_values);
    const egopd_predict_options o = read_predict_options(options);
    const PredictOptions po = call_predict_options(m.load, o);
    if (po.prompt) throw ArgumentError("counterfactual varies prompt fields: give --meta (or nothing), not --prompt");
    const ClipSource src = call_clip_source(o, po, model_hooks(m));
    const RunHooks hooks = call_hooks(m, o);
    ComputeScope scope(m);
    const PredictModel& pm = model_for(m, po.size);
    std::vector<ClipOutcome> outcomes = counterfactual_clip(pm, po, src, vary, po.out_dir, hooks);
    std::vector<std::unique_ptr<egopd_result>> out;
    for (ClipOutcome& c : outcomes) {
      out.push_back(std::make_unique<egopd_result>());
      out.back()->c = std::move(c);
    }
    for (size_t i = 0; i < out.size(); ++i) results[i] = out[i].release();
  });
}

int64_t egopd_result_frames(const egopd_result* r) { return r ? r->c.frames : 0; }
int64_t egopd_result_size(const egopd_result* r) { return r ? r->c.size : 0; }
int64_t egopd_result_num_taxels(const egopd_result* r) { return r ? r->c.num_taxels : 0; }
const double* egopd_result_taxels(const egopd_result* r) { return r ? r->c.taxels_n.data() : nullptr; }
const float* egopd_result_heatmaps(const egopd_result* r) { return r ? r->c.heatmaps.data() : nullptr; }
const double* egopd_result_total_force(const egopd_result* r) { return r ? r->c.total_force_n.data() : nullptr; }
const uint8_t* egopd_result_contact(const egopd_result* r) { return r ? r->c.contact.data() : nullptr; }
double egopd_result_mean_force(const egopd_result* r) { return r ? r->c.mean_total_force_n : 0; }
double egopd_result_peak_force(const egopd_result* r) { return r ? r->c.peak_total_force_n : 0; }
double egopd_result_seconds(const egopd_result* r) { return r ? r->c.seconds : 0; }
const char* egopd_result_summary_json(const egopd_result* r) { return r ? r->c.summary_json.c_str() : ""; }
const char* egopd_result_variant_value(const egopd_result* r) { return r ? r->c.variant_value.c_str() : ""; }
const char* egopd_result_variant_folder(const egopd_result* r) { return r ? r->c.variant_folder.c_str() : ""; }
void egopd_result_free(egopd_result* r) { delete r; }

}  // extern "C"
