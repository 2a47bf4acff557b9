#include "scheduler/euler.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"

namespace egopd {

namespace {
void require_string(const Config& cfg, const std::string& key, const std::string& want, bool optional = false) {
  if (optional && !cfg.has(key)) return;
  const std::string got = cfg.get_string(key);
  if (got != want) cfg.fail(key, "unsupported value '" + got + "' (only '" + want + "' is implemented)");
}
}  // namespace

EulerSampler::EulerSampler(const Config& cfg) {
  require_string(cfg, "prediction_type", "v_prediction");
  require_string(cfg, "timestep_type", "continuous");
  // "leading" selects init_noise_sigma = sqrt(max sigma^2 + 1) (the only combination SVD-xt uses).
  require_string(cfg, "timestep_spacing", "leading");
  require_string(cfg, "final_sigmas_type", "zero", /*optional=*/true);
  if (!cfg.get_bool("use_karras_sigmas", false))
    cfg.fail("use_karras_sigmas", "only Karras sigmas (true) are implemented");
  for (const char* key : {"use_exponential_sigmas", "use_beta_sigmas"})
    if (cfg.get_bool(key, false)) cfg.fail(key, "not implemented (only Karras sigmas)");
  // Without explicit bounds diffusers would derive them from the beta schedule, which is not implemented.
  sigma_min_ = cfg.get_double("sigma_min", kSigmaRange);
  sigma_max_ = cfg.get_double("sigma_max", kSigmaRange);
  if (!(sigma_min_ > 0)) cfg.fail("sigma_min", "must be > 0");
  if (!(sigma_max_ > sigma_min_)) cfg.fail("sigma_max", "must be > sigma_min");
}

void EulerSampler::set_timesteps(int n) {
  if (n < 1) throw Error("euler sampler: number of steps must be >= 1, got " + std::to_string(n));
  // numpy linspace(0, 1, n): i * (1 / (n - 1)), the last value exactly 1.
  std::vector<double> ramp(n, 0.0);
  if (n > 1) {
    const double step = 1.0 / double(n - 1);
    for (int i = 0; i < n; ++i) ramp[i] = double(i) * step;
    ramp[n - 1] = 1.0;
  }
  const std::vector<double> s = karras_sigmas(ramp, sigma_min_, sigma_max_, 7.0);
  sigmas_.assign(n + 1, 0.0f);
  for (int i = 0; i < n; ++i) sigmas_[i] = float(s[i]);
  timesteps_.resize(n);
  for (int i = 0; i < n; ++i) timesteps_[i] = double(0.25f * std::log(sigmas_[i]));  // float32 c_noise
  const float smax = *std::max_element(sigmas_.begin(), sigmas_.end());
  init_noise_sigma_ = double(std::sqrt(smax * smax + 1.0f));
}

float EulerSampler::input_scale_denominator(int i) const {
  const float s = sigmas_[i];
  return std::sqrt(s * s + 1.0f);
}

void EulerSampler::step(const float* v, const float* x, const float*, float* out, int64_t n, int i) const {
  check_step(i);
  // s_churn = 0: sigma_hat = sigma, no noise. All float32 in the reference's order.
  const float s = sigmas_[i];
  const float q = s * s + 1.0f;
  const float c_out = -s / std::sqrt(q);
  const float dt = sigmas_[i + 1] - s;
  for (int64_t k = 0; k < n; ++k) {
    const float x0 = v[k] * c_out + x[k] / q;
    const float d = (x[k] - x0) / s;
    out[k] = x[k] + d * dt;
  }
}

}  // namespace egopd
