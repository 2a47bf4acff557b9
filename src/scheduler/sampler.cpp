#include "scheduler/sampler.h"

#include <cmath>
#include <filesystem>

#include "core/error.h"
#include "scheduler/animatelcm.h"
#include "scheduler/euler.h"

namespace egopd {
namespace fs = std::filesystem;

std::vector<double> karras_sigmas(const std::vector<double>& ramp, double sigma_min, double sigma_max, double rho) {
  const double min_inv_rho = std::pow(sigma_min, 1.0 / rho);
  const double max_inv_rho = std::pow(sigma_max, 1.0 / rho);
  std::vector<double> s(ramp.size());
  for (size_t i = 0; i < ramp.size(); ++i) s[i] = std::pow(max_inv_rho + ramp[i] * (min_inv_rho - max_inv_rho), rho);
  return s;
}

void Sampler::check_step(int i) const {
  if (timesteps_.empty()) throw Error(std::string(name()) + " sampler: set_timesteps() was not called");
  if (i < 0 || i >= num_steps())
    throw Error(std::string(name()) + " sampler: step " + std::to_string(i) + " outside 0.." +
                std::to_string(num_steps() - 1));
}

void Sampler::init_latents(const float* noise, float* out, int64_t n) const {
  const float s = float(init_noise_sigma());
  for (int64_t k = 0; k < n; ++k) out[k] = noise[k] * s;
}

Tensor Sampler::init_latents(const Tensor& noise) const {
  Tensor out(noise.shape());
  init_latents(noise.data(), out.data(), noise.numel());
  return out;
}

void Sampler::scale_model_input(const float* x, float* out, int64_t n, int i) const {
  check_step(i);
  const float den = input_scale_denominator(i);
  for (int64_t k = 0; k < n; ++k) out[k] = x[k] / den;
}

Tensor Sampler::scale_model_input(const Tensor& x, int i) const {
  Tensor out(x.shape());
  scale_model_input(x.data(), out.data(), x.numel(), i);
  return out;
}

Tensor Sampler::step(const Tensor& v, int i, const Tensor& x, const Tensor* noise) const {
  if (v.shape() != x.shape())
    throw Error(std::string(name()) + " sampler: model output " + v.shape().str() + " does not match latent " +
                x.shape().str());
  check_step(i);
  const float* z = nullptr;
  if (step_needs_noise(i)) {
    if (!noise) throw Error(std::string(name()) + " sampler: step " + std::to_string(i) + " needs a noise tensor");
    if (noise->shape() != x.shape())
      throw Error(std::string(name()) + " sampler: step noise " + noise->shape().str() + " does not match latent " +
                  x.shape().str());
    z = noise->data();
  }
  Tensor out(x.shape());
  step(v.data(), x.data(), z, out.data(), x.numel(), i);
  return out;
}

std::unique_ptr<Sampler> make_sampler(const Config& cfg) {
  const std::string cls = cfg.get_string("_class_name");
  if (cls == "EulerDiscreteScheduler") return std::make_unique<EulerSampler>(cfg);
  if (cls == "AnimateLCMSVDStochasticIterativeScheduler") return std::make_unique<AnimateLcmSampler>(cfg);
  cfg.fail("_class_name", "unsupported scheduler '" + cls +
                              "' (supported: EulerDiscreteScheduler, AnimateLCMSVDStochasticIterativeScheduler)");
}

std::unique_ptr<Sampler> load_sampler(const std::string& scheduler_dir_or_file) {
  const fs::path p(scheduler_dir_or_file);
  fs::path file = p;
  if (fs::is_directory(p)) {
    file = p / "scheduler_config.json";
    if (!fs::exists(file) && fs::exists(p / "scheduler" / "scheduler_config.json"))
      file = p / "scheduler" / "scheduler_config.json";
  }
  if (!fs::exists(file)) throw Error(file.string() + ": scheduler config not found");
  return make_sampler(Config::load(file.string()));
}

}  // namespace egopd
