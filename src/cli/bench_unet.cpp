// `egopd bench unet`: one or more denoiser evaluations of a real-size U-Net with deterministic random weights, after
// untimed warm-up evaluations (the first evaluation of a process pays the first touch of the weights, activations
// and kernel scratch: up to 40% slower than the steady state of a sampler's later steps). The weights are
// written once into the cache folder and reused (bench_synthetic_weights).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"
#include "core/kernels/gemm.h"
#include "core/kernels/kernel_profile.h"
#include "core/threading.h"
#include "core/timing.h"
#include "unet3d/unet.h"

namespace egopd {

DType parse_weight_dtype(const std::string& s, const std::string& option) {
  if (s == "f32") return DType::F32;
  if (s == "f16") return DType::F16;
  if (s == "bf16") return DType::BF16;
  throw Error("--" + option + " must be f32, f16 or bf16 (got '" + s + "')");
}

namespace {

double lower_median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[(v.size() - 1) / 2];
}

// --precisions fp32,bf16,...: the precisions to alternate (empty without the flag).
std::vector<Precision> alternated_precisions(const Args& a) {
  if (!a.has("precisions")) return {};
  if (a.has("precision")) throw Error("bench unet: give --precision or --precisions, not both");
  std::vector<Precision> out;
  std::stringstream list(a.get("precisions", ""));
  for (std::string name; std::getline(list, name, ',');) {
    Precision p;
    if (!parse_precision(name.c_str(), &p))
      throw Error("bench unet: --precisions: '" + name + "' is not fp32, bf16 or int8");
    for (Precision q : out)
      if (q == p) throw Error("bench unet: --precisions names " + name + " twice");
    out.push_back(p);
  }
  if (out.size() < 2) throw Error("bench unet: --precisions needs two or more of fp32, bf16, int8 (e.g. fp32,bf16)");
  return out;
}

// Wall and CPU seconds of each precision's timed evaluations, in round order.
struct RoundTimes {
  std::vector<std::vector<double>> wall, cpu;
};

// `warmup` untimed rounds, then `evals` timed ones (`before_timing` runs between them), each round one evaluation per
// precision in the order given (evaluate(i): one evaluation in precisions[i]). One precision: plain repeated
// evaluations in it. Several: on a shared machine whose speed drifts over minutes, the ratio of two evaluations a few
// seconds apart moves far less than that of two runs.
RoundTimes timed_rounds(const std::vector<Precision>& precisions, int64_t warmup, int64_t evals,
                        const std::function<void()>& before_timing,
                        const std::function<std::pair<double, double>(size_t)>& evaluate) {
  const auto label = [&](Precision p) { return precisions.size() > 1 ? std::string(" ") + precision_name(p) : ""; };
  warm_up("unet", warmup, [&] {  // one round
    for (size_t i = 0; i < precisions.size(); ++i) set_precision(precisions[i]), evaluate(i);
  });
  before_timing();
  RoundTimes t;
  t.wall.resize(precisions.size());
  t.cpu.resize(precisions.size());
  for (int64_t e = 0; e < evals; ++e)
    for (size_t i = 0; i < precisions.size(); ++i) {
      set_precision(precisions[i]);
      const auto [wall, cpu_s] = evaluate(i);
      t.wall[i].push_back(wall);
      t.cpu[i].push_back(cpu_s);
      std::fprintf(stderr, "bench unet: evaluation %lld/%lld%s %.2f s\n", (long long)(e + 1), (long long)evals,
                   label(precisions[i]).c_str(), wall);
    }
  set_precision(precisions[0]);  // the report's own fields are the first precision's
  return t;
}

// What one precision's timed evaluations recorded: stage times, and the kernel calls under --kernel-profile.
struct PrecisionProfile {
  StageTimes stages;
  std::map<std::string, KernelProfileEntry> kernels;  // by kernel and shape, summed over the evaluations
  void add_kernels(const std::vector<KernelProfileEntry>& entries) {
    for (const KernelProfileEntry& e : entries) {
      KernelProfileEntry& k = kernels[e.kernel];
      k.kernel = e.kernel;
      k.calls += e.calls;
      k.seconds += e.seconds;
      k.flop += e.flop;
    }
  }
  std::vector<KernelProfileEntry> kernel_list() const {  // slowest first, as kernel_profile() gives them
    std::vector<KernelProfileEntry> out;
    for (const auto& [name, e] : kernels) out.push_back(e);
    std::sort(out.begin(), out.end(), [](const auto& x, const auto& y) { return x.seconds > y.seconds; });
    return out;
  }
};

nlohmann::ordered_json stage_seconds(const StageTimes& stages, int64_t evals) {
  nlohmann::ordered_json br = nlohmann::ordered_json::object();
  for (const auto& [k, v] : stages.entries()) br[k] = v / double(evals);
  return br;
}

// Seconds per evaluation of each kind of kernel call (gemm, gemm_geglu, conv2d, conv_temporal3, attention).
std::map<std::string, double> kind_seconds(const PrecisionProfile& p, int64_t evals) {
  std::map<std::string, double> out;
  for (const auto& [name, e] : p.kernels) out[name.substr(0, name.find(' '))] += e.seconds / double(evals);
  return out;
}

// --precisions: each precision's seconds per round and lower median, its stage times and (--kernel-profile) kernel
// profile, and the first precision's time over each other's: per round and the median of those, per stage and per
// kind of kernel call (the same layers, evaluated seconds apart).
nlohmann::ordered_json alternating_report(const std::vector<Precision>& precisions, const RoundTimes& t,
                                          const std::vector<PrecisionProfile>& profiles, bool kernels) {
  const int64_t evals = int64_t(t.wall[0].size());
  const auto speedups = [](const auto& first, const auto& other) {
    nlohmann::ordered_json out = nlohmann::ordered_json::object();
    for (const auto& entry : other) {  // (not a structured binding: clang 14 cannot capture those)
      const std::string& name = entry.first;
      const auto it = std::find_if(first.begin(), first.end(), [&](const auto& f) { return f.first == name; });
      if (it != first.end() && entry.second > 0) out[name] = it->second / entry.second;
    }
    return out;
  };
  nlohmann::ordered_json per = nlohmann::ordered_json::object();
  for (size_t i = 0; i < precisions.size(); ++i) {
    nlohmann::ordered_json row;
    row["seconds_per_round"] = t.wall[i];
    row["seconds"] = lower_median(t.wall[i]);
    row["cpu_seconds"] = lower_median(t.cpu[i]);
    if (i > 0) {
      std::vector<double> ratio;
      for (size_t e = 0; e < t.wall[i].size(); ++e) ratio.push_back(t.wall[0][e] / t.wall[i][e]);
      row["speedup_per_round"] = ratio;
      row["speedup"] = median(ratio);  // over the first precision, same round
    }
    row["breakdown_seconds"] = stage_seconds(profiles[i].stages, evals);
    if (i > 0) row["breakdown_speedup"] = speedups(profiles[0].stages.entries(), profiles[i].stages.entries());
    if (kernels) {
      const std::map<std::string, double> kinds = kind_seconds(profiles[i], evals);
      row["kernel_kinds_seconds"] = kinds;
      if (i > 0) row["kernel_kinds_speedup"] = speedups(kind_seconds(profiles[0], evals), kinds);
      kernel_profile_fields(profiles[i].kernel_list(), evals, lower_median(t.wall[i]), row);
    }
    per[precision_name(precisions[i])] = row;
  }
  return per;
}

}  // namespace

int bench_unet(const Args& a) {
  const std::string config = a.get("config", "svd-xt");
  const int64_t frames = a.get_int("frames", 16);
  const int64_t size = a.get_int("size", 256);
  const DType dtype = parse_weight_dtype(a.get("dtype", "f16"), "dtype");
  const int64_t evals = a.get_int("evals", 1);
  const int64_t warmup = a.get_int("warmup", 1);
  const bool pifr = a.flag("pifr");
  const bool json = a.flag("json");
  const bool profile_kernels = a.flag("kernel-profile");
  const std::string weights_dir = a.get("weights", "");
  const std::vector<Precision> rounds_of = alternated_precisions(a);
  a.finish();
  if (config != "svd-xt") throw Error("bench unet: --config must be svd-xt (got '" + config + "')");
  if (frames < 1 || size < 64 || size % 64 || evals < 1 || warmup < 0)
    throw Error("bench unet: need --frames >= 1, --size a multiple of 64, --evals >= 1, --warmup >= 0");

  UNetConfig cfg = UNetConfig::svd_xt(pifr);
  std::shared_ptr<const WeightMap> weights;
  if (!weights_dir.empty()) {
    weights = std::make_shared<WeightMap>(WeightMap::load_dir(weights_dir, "diffusion_pytorch_model", "unet"));
  } else {
    auto recorder = std::make_shared<WeightMap>(WeightMap::recorder("unet"));
    UNetSpatioTemporal shape_only(cfg, recorder);
    weights = bench_synthetic_weights("unet", "unet", recorder->recorded(), dtype);
  }

  UNetSpatioTemporal unet(cfg, weights);
  const int64_t h = size / 8, w = size / 8;
  Tensor sample({1, frames, cfg.in_channels, h, w}), ehs({1, 1, cfg.cross_attention_dim[0]}), ids({1, 3});
  for (int64_t i = 0; i < sample.numel(); ++i) sample[i] = float((i * 7919) % 2001) / 1000.0f - 1.0f;
  for (int64_t i = 0; i < ehs.numel(); ++i) ehs[i] = float((i * 104729) % 2001) / 1000.0f - 1.0f;
  ids[0] = 4, ids[1] = 127, ids[2] = 0.02f;
  Tensor text;
  if (pifr) {
    text = Tensor({1, 77, cfg.pifr_text_dim});
    for (int64_t i = 0; i < text.numel(); ++i) text[i] = float((i * 31) % 2001) / 1000.0f - 1.0f;
  }
  UNetConditioning cond = unet.prepare(ehs, pifr ? &text : nullptr);

  // One evaluation in precisions[i]: wall and CPU seconds. Timed ones record into profiles[i].
  const std::vector<Precision> precisions = rounds_of.empty() ? std::vector<Precision>{precision()} : rounds_of;
  std::vector<PrecisionProfile> profiles(precisions.size());
  bool timing = false;
  const auto evaluate = [&](size_t i) {
    if (timing) unet.set_profile(&profiles[i].stages);
    auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_seconds();
    Tensor v = unet.forward(sample, 1.6377700567245483f, ids, cond);
    const double cpu_s = process_cpu_seconds() - c0, wall = seconds_since(t0);
    if (!std::isfinite(v[0])) throw Error("bench unet: non-finite output");
    if (timing && profile_kernels) {  // each precision's calls apart
      profiles[i].add_kernels(kernel_profile());
      clear_kernel_profile();
    }
    return std::make_pair(wall, cpu_s);
  };
  const auto fl = unet.flops(1, frames, h, w, 1, pifr ? 77 : 0);
  BenchReport r;
  r.target = "unet";
  r.gflop = fl.executed / 1e9;
  r.threads = num_threads();
  r.extra["config"] = config;
  r.extra["frames"] = frames;
  r.extra["latent"] = std::to_string(h) + "x" + std::to_string(w);
  const StoredTensor* probe = weights->find("conv_in.weight");  // with --weights: what the files hold
  r.extra["dtype"] = dtype_name(probe ? probe->dtype : dtype);
  r.extra["pifr"] = pifr;
  r.extra["evaluations"] = evals;
  r.extra["warmup_evaluations"] = warmup;
  r.extra["gflop_pytorch_count"] = fl.total / 1e9;
  r.extra["weights_bytes"] = weights->total_bytes();
  // (The conditioning above was prepared in --precision's arithmetic, fp32 under --precisions; untimed either way.)
  const RoundTimes t = timed_rounds(precisions, warmup, evals, [&] {
    timing = true;
    set_kernel_profiling(profile_kernels);
  }, evaluate);
  r.seconds = lower_median(t.wall[0]);
  r.cpu_seconds = lower_median(t.cpu[0]);
  set_kernel_profiling(false);
  if (!rounds_of.empty()) {
    r.extra["alternating"] = alternating_report(precisions, t, profiles, profile_kernels);
  } else {
    r.extra["breakdown_seconds"] = stage_seconds(profiles[0].stages, evals);
    if (profile_kernels) kernel_profile_fields(profiles[0].kernel_list(), evals, r.seconds, r.extra);
  }
  print_bench_report(r, json);
  return 0;
}

}  // namespace egopd
