#pragma once
// diffusers EulerDiscreteScheduler restricted to the SVD-xt configuration (scheduler.md §1): Karras sigmas,
// v-prediction, continuous timesteps 0.25 ln(sigma), timestep_spacing "leading", final sigma 0, s_churn = 0.
#include "scheduler/sampler.h"

namespace egopd {

class EulerSampler : public Sampler {
 public:
  // Validates the config (errors name the file and field).
  explicit EulerSampler(const Config& cfg);
  EulerSampler(double sigma_min, double sigma_max) : sigma_min_(sigma_min), sigma_max_(sigma_max) {}

  const char* name() const override { return "euler"; }
  int default_steps() const override { return 25; }
  void set_timesteps(int n) override;  // any n >= 1
  double init_noise_sigma() const override { return init_noise_sigma_; }
  bool step_needs_noise(int) const override { return false; }
  void step(const float* v, const float* x, const float* noise, float* out, int64_t n, int i) const override;
  using Sampler::step;

 protected:
  float input_scale_denominator(int i) const override;

 private:
  double sigma_min_ = 0.002, sigma_max_ = 700.0;
  double init_noise_sigma_ = 0;
};

}  // namespace egopd
