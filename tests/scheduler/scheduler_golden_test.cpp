// The sampler golden cases: the schedule and trajectory of scheduler_euler, scheduler_lcm_4 and scheduler_lcm_8,
// checked against expected.safetensors with each case's own tolerances (max_abs and rel_l2, as compare.py).
// The tensors are read flat here (the trajectories are rank 6); the runner itself is checked below through
// load_golden_case when the core tensor supports that rank.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <map>

#include "core/config.h"
#include "core/dtype.h"
#include "core/golden.h"
#include "core/safetensors.h"
#include "scheduler/sampler.h"
#include "scheduler/scheduler_case.h"

namespace egopd {
namespace {

const std::string kGolden = std::string(EGOPD_TEST_DATA) + "/data/golden/";

std::map<std::string, std::vector<float>> read_flat(const std::string& path) {
  SafeTensorsFile f(path);
  std::map<std::string, std::vector<float>> m;
  for (const auto& t : f.tensors()) {
    std::vector<float> v(size_t(t.numel()));
    convert_to_f32(t.dtype, t.data, v.data(), v.size());
    m[t.name] = std::move(v);
  }
  return m;
}

void expect_within(const Config& spec, const std::string& name, const std::vector<float>& got,
                   const std::vector<float>& want) {
  ASSERT_EQ(got.size(), want.size()) << name;
  double max_abs = 0, num = 0, den = 0;
  for (size_t k = 0; k < got.size(); ++k) {
    const double d = double(got[k]) - double(want[k]);
    ASSERT_TRUE(std::isfinite(got[k])) << name << "[" << k << "]";
    max_abs = std::max(max_abs, std::fabs(d));
    num += d * d;
    den += double(want[k]) * want[k];
  }
  const double rel = den > 0 ? std::sqrt(num / den) : std::sqrt(num);
  const auto& tol = spec.json()["tolerance"][name];
  EXPECT_LE(max_abs, tol["max_abs"].get<double>()) << name;
  EXPECT_LE(rel, tol["rel_l2"].get<double>()) << name;
  std::printf("  %-20s max_abs %.3g (tol %.3g)  rel_l2 %.3g (tol %.3g)\n", name.c_str(), max_abs,
              tol["max_abs"].get<double>(), rel, tol["rel_l2"].get<double>());
}

void run_case(const std::string& name) {
  const std::string dir = kGolden + name;
  const Config spec = Config::load(dir + "/case.json");
  auto in = read_flat(dir + "/inputs.safetensors");
  auto exp = read_flat(dir + "/expected.safetensors");
  auto s = load_sampler(dir + "/model");
  const int n = int(spec.json()["args"]["num_inference_steps"].get<int>());
  s->set_timesteps(n);
  const std::vector<float>& noise = in.at("noise");
  const int64_t e = int64_t(noise.size());
  std::map<std::string, std::vector<float>> got;
  for (int i = 0; i < n; ++i) got["timesteps"].push_back(float(s->timesteps()[i]));
  got["sigmas"] = s->sigmas();
  got["init_noise_sigma"] = {float(s->init_noise_sigma())};
  std::vector<float> x(e), scaled(n * e), prev(n * e);
  s->init_latents(noise.data(), x.data(), e);
  got["latents_0"] = x;
  for (int i = 0; i < n; ++i) {
    s->scale_model_input(x.data(), scaled.data() + i * e, e, i);
    const float* z = s->step_needs_noise(i) ? in.at("step_noises").data() + i * e : nullptr;
    s->step(in.at("model_outputs").data() + i * e, x.data(), z, x.data(), e, i);
    std::copy(x.begin(), x.end(), prev.begin() + i * e);
  }
  got["scaled_model_inputs"] = scaled;
  got["prev_samples"] = prev;
  got["final_sample"] = x;
  std::printf("%s\n", name.c_str());
  for (auto it = spec.json()["outputs"].begin(); it != spec.json()["outputs"].end(); ++it)
    expect_within(spec, it.key(), got.at(it.key()), exp.at(it.key()));
}

TEST(SchedulerGolden, Euler25) { run_case("scheduler_euler"); }
TEST(SchedulerGolden, AnimateLcm4) { run_case("scheduler_lcm_4"); }
TEST(SchedulerGolden, AnimateLcm8) { run_case("scheduler_lcm_8"); }

TEST(SchedulerGolden, RngRunnerIsBitExact) {
  GoldenCase c = load_golden_case(kGolden + "rng");
  for (const auto& r : compare_case_outputs(c, run_rng_case(c))) {
    EXPECT_TRUE(r.ok) << r.name << " " << r.message;
    EXPECT_EQ(r.max_abs, 0.0) << r.name;
  }
}

TEST(SchedulerGolden, SamplerRunnersThroughGoldenCase) {
  if (kMaxDims < 6) GTEST_SKIP() << "the sampler cases hold rank-6 tensors; core Tensor supports rank " << kMaxDims;
  for (const char* name : {"scheduler_euler", "scheduler_lcm_4", "scheduler_lcm_8"}) {
    GoldenCase c = load_golden_case(kGolden + name);
    const CaseOutputs out =
        c.component == "scheduler_euler" ? run_scheduler_euler_case(c) : run_scheduler_lcm_case(c);
    for (const auto& r : compare_case_outputs(c, out))
      EXPECT_TRUE(r.ok) << name << " " << r.name << " " << r.message << " max_abs " << r.max_abs << " rel_l2 "
                        << r.rel_l2;
  }
}

}  // namespace
}  // namespace egopd
