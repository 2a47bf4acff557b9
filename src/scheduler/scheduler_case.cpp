// Golden-case runners: `rng` (torch-compatible draws) and the sampler trajectories `scheduler_euler` /
// `scheduler_lcm` (schedule + a loop driven by given model outputs and re-noising noise).
#include <algorithm>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/golden.h"
#include "core/rng.h"
#include "scheduler/sampler.h"
#include "scheduler/scheduler_case.h"

namespace egopd {

CaseOutputs run_rng_case(const GoldenCase& c) {
  CaseOutputs out;
  const auto& draws = c.args.json().value("draws", nlohmann::json::array());
  if (!draws.is_array() || draws.empty()) c.args.fail("draws", "expected a non-empty list of {output, seed, shape}");
  for (const auto& d : draws) {
    if (!d.is_object() || !d.contains("output") || !d.contains("seed") || !d.contains("shape"))
      c.args.fail("draws", "each entry needs output, seed and shape");
    const Shape shape(d["shape"].get<std::vector<int64_t>>());
    // A negative seed is taken as its two's complement, like torch.
    TorchGenerator g(uint64_t(d["seed"].get<int64_t>()));
    out.tensors[d["output"].get<std::string>()] = g.randn(shape);
  }
  return out;
}

namespace {

Shape with_leading(int64_t n, const Shape& s) {
  std::vector<int64_t> v{n};
  for (int64_t d : s.vec()) v.push_back(d);
  return Shape(v);
}

// Runs the loop of scheduler.md §2 with the case's fake model outputs (and, for AnimateLCM, step noises).
CaseOutputs run_sampler_case(const GoldenCase& c, const std::string& want_sampler) {
  auto sampler = load_sampler(c.model_dir());
  if (want_sampler != sampler->name())
    throw Error("case " + c.name + ": component " + c.component + " but the scheduler config selects the " +
                sampler->name() + " sampler");
  const int n = int(c.args.get_int("num_inference_steps"));
  sampler->set_timesteps(n);

  const Tensor& noise = c.input("noise");
  const int64_t elems = noise.numel();
  const Tensor& model_outputs = c.input("model_outputs");
  if (model_outputs.numel() != n * elems)
    throw Error("case " + c.name + ": model_outputs " + model_outputs.shape().str() + " is not [" +
                std::to_string(n) + ", " + noise.shape().str() + "]");
  const Tensor* step_noises = nullptr;
  if (c.has_input("step_noises")) {
    step_noises = &c.input("step_noises");
    if (step_noises->numel() != n * elems)
      throw Error("case " + c.name + ": step_noises " + step_noises->shape().str() + " is not [" +
                  std::to_string(n) + ", " + noise.shape().str() + "]");
  }

  CaseOutputs out;
  Tensor timesteps(Shape{n}), sigmas(Shape{n + 1});
  for (int i = 0; i < n; ++i) timesteps[i] = float(sampler->timesteps()[i]);
  for (int i = 0; i <= n; ++i) sigmas[i] = sampler->sigmas()[i];
  Tensor latents = sampler->init_latents(noise);
  Tensor scaled(with_leading(n, noise.shape())), prev(with_leading(n, noise.shape()));
  out.tensors["latents_0"] = latents.clone();
  for (int i = 0; i < n; ++i) {
    sampler->scale_model_input(latents.data(), scaled.data() + i * elems, elems, i);
    const float* z = nullptr;
    if (sampler->step_needs_noise(i)) {
      if (!step_noises) throw Error("case " + c.name + ": the sampler re-noises but inputs lack step_noises");
      z = step_noises->data() + i * elems;
    }
    sampler->step(model_outputs.data() + i * elems, latents.data(), z, latents.data(), elems, i);
    std::copy(latents.data(), latents.data() + elems, prev.data() + i * elems);
  }
  out.tensors["timesteps"] = timesteps;
  out.tensors["sigmas"] = sigmas;
  out.tensors["init_noise_sigma"] = Tensor::full(Shape{1}, float(sampler->init_noise_sigma()));
  out.tensors["scaled_model_inputs"] = scaled;
  out.tensors["prev_samples"] = prev;
  out.tensors["final_sample"] = latents;
  return out;
}

}  // namespace

CaseOutputs run_scheduler_euler_case(const GoldenCase& c) { return run_sampler_case(c, "euler"); }
CaseOutputs run_scheduler_lcm_case(const GoldenCase& c) { return run_sampler_case(c, "animatelcm"); }

}  // namespace egopd
