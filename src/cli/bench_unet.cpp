// `egopd bench unet`: one or more denoiser evaluations of a real-size U-Net with deterministic random weights, after
// untimed warm-up evaluations (the first evaluation of a process pays the first touch of the weights, activations
// and kernel scratch: up to 40% slower than the steady state of a sampler's later steps). The weights are
// written once into the cache folder and reused (bench_synthetic_weights).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
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
  if (a.flag("kernel-profile")) throw Error("bench unet: --kernel-profile takes one --precision, not --precisions");
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

// Rounds of one evaluation per precision, in the order given, after `warmup` rounds: on a shared machine whose speed
// drifts over minutes, the ratio of two evaluations a few seconds apart moves far less than that of two runs. The
// report: each precision's seconds per round and lower median, and the first precision's time over each other's,
// per round and the median of those.
int bench_unet_alternating(const std::vector<Precision>& precisions, int64_t evals, int64_t warmup, BenchReport r,
                           bool json, const std::function<std::pair<double, double>()>& evaluate) {
  for (int64_t e = 0; e < warmup; ++e)
    for (Precision p : precisions) {
      set_precision(p);
      warm_up(std::string("unet ") + precision_name(p), 1, [&] { evaluate(); });
    }
  std::vector<std::vector<double>> secs(precisions.size()), cpu(precisions.size());
  for (int64_t e = 0; e < evals; ++e)
    for (size_t i = 0; i < precisions.size(); ++i) {
      set_precision(precisions[i]);
      const auto [wall, cpu_s] = evaluate();
      secs[i].push_back(wall);
      cpu[i].push_back(cpu_s);
      std::fprintf(stderr, "bench unet: round %lld/%lld %s %.2f s\n", (long long)(e + 1), (long long)evals,
                   precision_name(precisions[i]), wall);
    }
  nlohmann::ordered_json per = nlohmann::ordered_json::object();
  for (size_t i = 0; i < precisions.size(); ++i) {
    nlohmann::ordered_json row;
    row["seconds_per_round"] = secs[i];
    row["seconds"] = lower_median(secs[i]);
    row["cpu_seconds"] = lower_median(cpu[i]);
    if (i > 0) {
      std::vector<double> ratio;
      for (int64_t e = 0; e < evals; ++e) ratio.push_back(secs[0][size_t(e)] / secs[i][size_t(e)]);
      row["speedup_per_round"] = ratio;
      row["speedup"] = median(ratio);  // over the first precision, same round
    }
    per[precision_name(precisions[i])] = row;
  }
  set_precision(precisions[0]);  // the report's own fields are the first precision's
  r.seconds = lower_median(secs[0]);
  r.cpu_seconds = lower_median(cpu[0]);
  r.extra["alternating"] = per;
  print_bench_report(r, json);
  return 0;
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

  // One evaluation: wall and CPU seconds.
  const auto evaluate = [&] {
    auto t0 = std::chrono::steady_clock::now();
    const double c0 = process_cpu_seconds();
    Tensor v = unet.forward(sample, 1.6377700567245483f, ids, cond);
    const double cpu_s = process_cpu_seconds() - c0, wall = seconds_since(t0);
    if (!std::isfinite(v[0])) throw Error("bench unet: non-finite output");
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
  if (!rounds_of.empty()) return bench_unet_alternating(rounds_of, evals, warmup, r, json, evaluate);

  warm_up("unet", warmup, [&] { evaluate(); });
  StageTimes stages;
  unet.set_profile(&stages);
  set_kernel_profiling(profile_kernels);
  std::vector<double> secs, cpu;
  for (int64_t e = 0; e < evals; ++e) {
    const auto [wall, cpu_s] = evaluate();
    secs.push_back(wall);
    cpu.push_back(cpu_s);
    std::fprintf(stderr, "bench unet: evaluation %lld/%lld %.2f s\n", (long long)(e + 1), (long long)evals, wall);
  }
  r.seconds = lower_median(secs);
  r.cpu_seconds = lower_median(cpu);
  nlohmann::ordered_json br = nlohmann::ordered_json::object();
  for (const auto& [k, v] : stages.entries()) br[k] = v / double(evals);
  r.extra["breakdown_seconds"] = br;
  if (profile_kernels) add_kernel_profile(r, evals);
  print_bench_report(r, json);
  return 0;
}

}  // namespace egopd
