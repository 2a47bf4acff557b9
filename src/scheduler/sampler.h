#pragma once
// Samplers of the SVD-xt family (scheduler.md): the Euler teacher sampler and the AnimateLCM-SVD consistency
// sampler share one interface. Both use the EDM v-prediction scalings with sigma_data = 1:
//   c_in = 1/sqrt(s^2+1), c_noise = 0.25 ln s, c_skip = 1/(s^2+1), c_out = -s/sqrt(s^2+1).
// Latent arithmetic is float32 in the reference's operation order; schedules follow the reference's precision
// (Karras sigmas in double, rounded to float32).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/config.h"
#include "core/tensor.h"

namespace egopd {

// Karras rho-schedule in double: (max^(1/rho) + r (min^(1/rho) - max^(1/rho)))^rho for each ramp value r.
std::vector<double> karras_sigmas(const std::vector<double>& ramp, double sigma_min, double sigma_max, double rho);

class Sampler {
 public:
  virtual ~Sampler() = default;
  virtual const char* name() const = 0;  // "euler" or "animatelcm"
  virtual int default_steps() const = 0;

  // Builds the schedule for n steps (error naming the valid range otherwise).
  virtual void set_timesteps(int n) = 0;
  int num_steps() const { return int(timesteps_.size()); }
  // The UNet `timestep` of each step (c_noise). Euler's are float32 values, AnimateLCM's float64 (the UNet
  // rounds to float32 either way).
  const std::vector<double>& timesteps() const { return timesteps_; }
  // num_steps() + 1 float32 noise levels, descending, the last one 0.
  const std::vector<float>& sigmas() const { return sigmas_; }

  // Scale of the initial noise (double as the reference holds it; multiplying float32 noise uses float(init)).
  virtual double init_noise_sigma() const = 0;
  // x_0 = noise * init_noise_sigma (float32).
  void init_latents(const float* noise, float* out, int64_t n) const;
  Tensor init_latents(const Tensor& noise) const;

  // UNet input of step i: x / sqrt(sigma_i^2 + sigma_data^2) (float32 division). out may alias x.
  void scale_model_input(const float* x, float* out, int64_t n, int i) const;
  Tensor scale_model_input(const Tensor& x, int i) const;

  // Whether step i consumes fresh N(0, 1) noise. A seeded run draws one latent-shaped tensor (torch-compatible
  // generator) before each such step. Euler: never; AnimateLCM: every step when num_steps() > 1 (also the last,
  // whose noise is multiplied by 0), never for a single step (the reference uses zeros there).
  virtual bool step_needs_noise(int i) const = 0;

  // One sampler step: v = the (guided) model output of step i, x = the current latent -> the next latent.
  // noise must be given when step_needs_noise(i); otherwise it is ignored (may be null). out may alias x.
  virtual void step(const float* v, const float* x, const float* noise, float* out, int64_t n, int i) const = 0;
  Tensor step(const Tensor& v, int i, const Tensor& x, const Tensor* noise = nullptr) const;

 protected:
  void check_step(int i) const;  // i in [0, num_steps())
  virtual float input_scale_denominator(int i) const = 0;  // sqrt(sigma_i^2 + sigma_data^2) in float32
  std::vector<double> timesteps_;
  std::vector<float> sigmas_;
};

// Picks the implementation by the config's "_class_name"; one-line error naming the file and field for anything
// unsupported. The schedule is empty until set_timesteps().
std::unique_ptr<Sampler> make_sampler(const Config& scheduler_config);
// Accepts a scheduler_config.json file, a folder holding one, or a model folder with scheduler/scheduler_config.json.
std::unique_ptr<Sampler> load_sampler(const std::string& scheduler_dir_or_file);

}  // namespace egopd
