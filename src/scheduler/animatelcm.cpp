#include "scheduler/animatelcm.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace egopd {

AnimateLcmSampler::AnimateLcmSampler(const Config& cfg) {
  p_.num_train_timesteps = int(cfg.get_int("num_train_timesteps", 40, IntRange{1, 1000000}));
  p_.sigma_min = cfg.get_double("sigma_min", kSigmaRange);
  p_.sigma_max = cfg.get_double("sigma_max", kSigmaRange);
  p_.sigma_data = cfg.get_double("sigma_data", kSigmaRange);
  p_.s_noise = cfg.get_double("s_noise", 1.0, RealRange{0, 100});
  p_.rho = cfg.get_double("rho", 7.0, RealRange{0, 1000, true});
  if (!cfg.has("clip_denoised")) cfg.fail("clip_denoised", "missing");
  p_.clip_denoised = cfg.get_bool("clip_denoised", false);
  if (p_.num_train_timesteps < 2) cfg.fail("num_train_timesteps", "must be >= 2");
  if (!(p_.sigma_min > 0)) cfg.fail("sigma_min", "must be > 0");
  if (!(p_.sigma_max > p_.sigma_min)) cfg.fail("sigma_max", "must be > sigma_min");
  if (!(p_.sigma_data > 0)) cfg.fail("sigma_data", "must be > 0");
  if (!(p_.rho > 0)) cfg.fail("rho", "must be > 0");
}

void AnimateLcmSampler::set_timesteps(int n) {
  const int T = p_.num_train_timesteps;
  if (n < 1 || n > T)
    throw Error("animatelcm sampler: number of steps must be in 1.." + std::to_string(T) + ", got " +
                std::to_string(n));
  const int step_ratio = T / n;
  std::vector<double> ramp(n);
  for (int j = 0; j < n; ++j) ramp[j] = double(j * step_ratio) / double(T - 1);
  const std::vector<double> s = karras_sigmas(ramp, p_.sigma_min, p_.sigma_max, p_.rho);
  timesteps_.resize(n);
  sigmas_.assign(n + 1, 0.0f);
  for (int j = 0; j < n; ++j) {
    timesteps_[j] = 0.25 * std::log(s[j] + 1e-44);  // double c_noise from the double sigmas
    sigmas_[j] = float(s[j]);
  }
}

double AnimateLcmSampler::init_noise_sigma() const { return std::sqrt(p_.sigma_max * p_.sigma_max + 1.0); }

bool AnimateLcmSampler::step_needs_noise(int) const { return num_steps() > 1; }

float AnimateLcmSampler::input_scale_denominator(int i) const {
  const float s = sigmas_[i];
  return std::sqrt(s * s + float(p_.sigma_data * p_.sigma_data));
}

void AnimateLcmSampler::step(const float* v, const float* x, const float* noise, float* out, int64_t n,
                             int i) const {
  check_step(i);
  if (step_needs_noise(i) && !noise)
    throw Error("animatelcm sampler: step " + std::to_string(i) + " needs a noise tensor");
  // EDM v-prediction scalings (float32 from the float32 sigma).
  const float s = sigmas_[i];
  const float sd2 = float(p_.sigma_data * p_.sigma_data);
  const float q = s * s + sd2;
  const float c_skip = sd2 / q;
  const float c_out = -s * float(p_.sigma_data) / std::sqrt(q);
  const float sigma_next = std::clamp(sigmas_[i + 1], 0.0f, float(p_.sigma_max));
  const float s_noise = float(p_.s_noise);
  const bool renoise = step_needs_noise(i);
  for (int64_t k = 0; k < n; ++k) {
    float denoised = c_out * v[k] + c_skip * x[k];
    if (p_.clip_denoised) denoised = std::clamp(denoised, -1.0f, 1.0f);
    out[k] = renoise ? denoised + (noise[k] * s_noise) * sigma_next : denoised;
  }
}

}  // namespace egopd
