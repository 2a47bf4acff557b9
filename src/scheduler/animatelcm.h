#pragma once
// AnimateLCM-SVD stochastic iterative (consistency) sampler (scheduler.md §3): Karras sigmas at integer steps
// k_j = j * (T div N) of a T = num_train_timesteps grid, denoise with the EDM v-scalings, re-noise to the next sigma.
#include "scheduler/sampler.h"

namespace egopd {

struct AnimateLcmParams {
  int num_train_timesteps = 40;
  double sigma_min = 0.002, sigma_max = 700.0, sigma_data = 1.0, s_noise = 1.0, rho = 7.0;
  bool clip_denoised = false;
};

class AnimateLcmSampler : public Sampler {
 public:
  // Validates the config. sigma_min, sigma_max, sigma_data and clip_denoised are required: the class defaults
  // (80, 0.5, true) differ from what AnimateLCM-SVD-xt runs with, so a missing field is an error, not a guess.
  explicit AnimateLcmSampler(const Config& cfg);
  explicit AnimateLcmSampler(const AnimateLcmParams& p) : p_(p) {}

  const char* name() const override { return "animatelcm"; }
  int default_steps() const override { return 8; }
  void set_timesteps(int n) override;  // 1 <= n <= num_train_timesteps
  double init_noise_sigma() const override;
  bool step_needs_noise(int i) const override;
  void step(const float* v, const float* x, const float* noise, float* out, int64_t n, int i) const override;
  using Sampler::step;
  const AnimateLcmParams& params() const { return p_; }

 protected:
  float input_scale_denominator(int i) const override;

 private:
  AnimateLcmParams p_;
};

}  // namespace egopd
