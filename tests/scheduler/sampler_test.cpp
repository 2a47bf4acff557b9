// Sampler schedules against the worked tables of scheduler.md (§1.5, §3.4), step formulas against a plain
// double-precision evaluation, any-N properties and config errors.
#include "core/json_text.h"
#include "scheduler/sampler.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "scheduler/animatelcm.h"
#include "scheduler/euler.h"

namespace egopd {
namespace {
namespace fs = std::filesystem;

const std::string kGolden = std::string(EGOPD_TEST_DATA) + "/data/golden";

std::unique_ptr<Sampler> euler() { return load_sampler(kGolden + "/scheduler_euler/model"); }
std::unique_ptr<Sampler> lcm() { return load_sampler(kGolden + "/scheduler_lcm_8/model"); }

// scheduler.md §1.5: sigma_i, t_i, c_in, c_out, c_skip (float32 values printed with 9 significant digits,
// which identify a float32 exactly).
struct EulerRow {
  float sigma, t, c_in, c_out, c_skip;
};
const EulerRow kEuler25[] = {
    {700.0f, 1.63777006f, 0.0014285699f, -0.999998927f, 2.04081221e-06f},
    {545.729248f, 1.57553077f, 0.00183240743f, -0.999998331f, 3.35771711e-06f},
    {421.569122f, 1.51099598f, 0.00237208349f, -0.999997199f, 5.62678042e-06f},
    {322.453674f, 1.44398987f, 0.00310120569f, -0.999995172f, 9.61747719e-06f},
    {244.023071f, 1.37431574f, 0.004097939f, -0.999991596f, 1.6793103e-05f},
    {182.547134f, 1.30175209f, 0.00547795463f, -0.99998498f, 3.00079901e-05f},
    {134.854446f, 1.22604895f, 0.00741519872f, -0.999972522f, 5.49851684e-05f},
    {98.2671356f, 1.14692247f, 0.0101758149f, -0.999948204f, 0.000103547223f},
    {70.5408401f, 1.06404793f, 0.0141747603f, -0.999899507f, 0.000200923838f},
    {49.8097916f, 0.977052867f, 0.0200723298f, -0.999798536f, 0.000402898382f},
    {34.5367393f, 0.885505915f, 0.028942544f, -0.999581099f, 0.000837670814f},
    {23.4675121f, 0.78890425f, 0.0425734669f, -0.999093354f, 0.00181250006f},
    {15.5899677f, 0.686656892f, 0.0640122667f, -0.997949123f, 0.00409756973f},
    {10.0971298f, 0.578062773f, 0.0985558778f, -0.995131493f, 0.00971326139f},
    {6.35426569f, 0.462281585f, 0.155461237f, -0.987841964f, 0.0241681952f},
    {3.86969733f, 0.338294059f, 0.25019899f, -0.968194425f, 0.0625995398f},
    {2.2691164f, 0.204847634f, 0.403275341f, -0.9150787f, 0.162631005f},
    {1.27317727f, 0.0603788905f, 0.61768651f, -0.786424458f, 0.381536633f},
    {0.678146005f, -0.0970981643f, 0.827639341f, -0.561260283f, 0.68498683f},
    {0.339378148f, -0.270160079f, 0.946952045f, -0.321374834f, 0.896718204f},
    {0.157404646f, -0.462233841f, 0.987837434f, -0.155490205f, 0.975822806f},
    {0.0663990751f, -0.678018034f, 0.997802794f, -0.0662531853f, 0.995610535f},
    {0.0248025805f, -0.924201906f, 0.999692559f, -0.0247949548f, 0.999385238f},
    {0.00788249541f, -1.21077764f, 0.999969006f, -0.0078822514f, 0.999937892f},
    {0.00200000009f, -1.55365205f, 0.999997973f, -0.00199999614f, 0.999995947f},
};

TEST(EulerSampler, Svd25StepScheduleMatchesSpecTable) {
  auto s = euler();
  EXPECT_STREQ(s->name(), "euler");
  EXPECT_EQ(s->default_steps(), 25);
  s->set_timesteps(25);
  ASSERT_EQ(s->num_steps(), 25);
  ASSERT_EQ(s->sigmas().size(), 26u);
  EXPECT_EQ(s->sigmas()[25], 0.0f);
  // Exact float32 sigmas quoted in the spec.
  EXPECT_EQ(s->sigmas()[1], 545.729248046875f);
  EXPECT_EQ(s->sigmas()[2], 421.5691223144531f);
  EXPECT_EQ(s->sigmas()[3], 322.45367431640625f);
  EXPECT_EQ(s->sigmas()[4], 244.0230712890625f);
  EXPECT_EQ(s->timesteps()[0], 1.6377700567245483);
  EXPECT_EQ(s->init_noise_sigma(), 700.000732421875);
  for (int i = 0; i < 25; ++i) {
    const EulerRow& r = kEuler25[i];
    EXPECT_EQ(s->sigmas()[i], r.sigma) << i;
    EXPECT_EQ(float(s->timesteps()[i]), r.t) << i;
    EXPECT_EQ(double(float(s->timesteps()[i])), s->timesteps()[i]) << "Euler timesteps are float32 values";
    // c_in through scale_model_input of a 1: 1 / sqrt(sigma^2 + 1), one rounding either way.
    float one = 1.0f, cin;
    s->scale_model_input(&one, &cin, 1, i);
    EXPECT_NEAR(cin, r.c_in, 1e-7 * r.c_in) << i;
  }
}

TEST(EulerSampler, StepMatchesDoubleFormulaAndSpecScalings) {
  auto s = euler();
  s->set_timesteps(25);
  const float xs[4] = {0.5f, -1.25f, 3.0f, 100.0f}, vs[4] = {1.0f, -0.3f, 0.0f, 2.5f};
  for (int i = 0; i < 25; ++i) {
    const EulerRow& r = kEuler25[i];
    const double sig = s->sigmas()[i], next = s->sigmas()[i + 1];
    float out[4];
    s->step(vs, xs, nullptr, out, 4, i);
    for (int k = 0; k < 4; ++k) {
      // x0 with the spec's float32 scalings, then the Euler update, in double.
      const double x0 = double(r.c_out) * vs[k] + double(r.c_skip) * xs[k];
      const double want = xs[k] + (xs[k] - x0) / sig * (next - sig);
      EXPECT_NEAR(out[k], want, 2e-6 * (std::fabs(want) + std::fabs(xs[k]) + 1e-3)) << i << "," << k;
    }
  }
}

TEST(EulerSampler, LastStepReturnsDenoisedEstimate) {
  auto s = euler();
  s->set_timesteps(25);
  const float x = 0.75f, v = -0.4f;
  float out;
  s->step(&v, &x, nullptr, &out, 1, 24);
  const double sig = s->sigmas()[24];
  const double x0 = -sig / std::sqrt(sig * sig + 1) * v + x / (sig * sig + 1);
  EXPECT_NEAR(out, x0, 1e-6);
}

TEST(EulerSampler, AnyStepCountProperties) {
  auto s = euler();
  for (int n : {1, 2, 3, 7, 25, 50, 100}) {
    s->set_timesteps(n);
    ASSERT_EQ(s->num_steps(), n);
    ASSERT_EQ(int(s->sigmas().size()), n + 1);
    EXPECT_EQ(s->sigmas()[0], 700.0f) << n;
    EXPECT_EQ(s->sigmas()[n], 0.0f) << n;
    if (n > 1) {
      EXPECT_EQ(s->sigmas()[n - 1], 0.002f) << n;
    }
    for (int i = 0; i < n; ++i) {
      EXPECT_GT(s->sigmas()[i], s->sigmas()[i + 1]) << n << ":" << i;
      EXPECT_NEAR(s->timesteps()[i], 0.25 * std::log(double(s->sigmas()[i])), 2e-7) << n << ":" << i;
      EXPECT_FALSE(s->step_needs_noise(i));
    }
    EXPECT_EQ(s->init_noise_sigma(), 700.000732421875);
  }
  EXPECT_THROW(s->set_timesteps(0), Error);
}

TEST(EulerSampler, KarrasRampDoubleValues) {
  // rho = 7 schedule: ends are the bounds; the midpoint is ((a + b) / 2)^7 with a, b = bounds^(1/7).
  const auto k = karras_sigmas({0.0, 0.5, 1.0}, 0.002, 700.0, 7.0);
  EXPECT_NEAR(k[0], 700.0, 1e-10);
  EXPECT_NEAR(k[2], 0.002, 1e-15);
  const double mid = std::pow((std::pow(700.0, 1 / 7.0) + std::pow(0.002, 1 / 7.0)) / 2, 7.0);
  EXPECT_NEAR(k[1], mid, 1e-12);
}

struct LcmRow {
  float sigma;
  double c_noise;
  float sigma_next;
};
const LcmRow kLcm8[] = {
    {700.0f, 1.63777008376, 315.737396f},         {315.737396f, 1.43872771127, 128.56369f},
    {128.56369f, 1.21410611994, 45.8507233f},     {45.8507233f, 0.9563477463, 13.6784439f},
    {13.6784439f, 0.65395529282, 3.16661072f},    {3.16661072f, 0.288165466209, 0.496878415f},
    {0.496878415f, -0.174852477476, 0.0397536904f}, {0.0397536904f, -0.806263145204, 0.0f},
};
const LcmRow kLcm4[] = {
    {700.0f, 1.63777008376, 128.56369f},
    {128.56369f, 1.21410611994, 13.6784439f},
    {13.6784439f, 0.65395529282, 0.496878415f},
    {0.496878415f, -0.174852477476, 0.0f},
};

void expect_lcm_table(int n, const LcmRow* rows) {
  auto s = lcm();
  s->set_timesteps(n);
  ASSERT_EQ(s->num_steps(), n);
  ASSERT_EQ(int(s->sigmas().size()), n + 1);
  for (int i = 0; i < n; ++i) {
    EXPECT_EQ(s->sigmas()[i], rows[i].sigma) << n << ":" << i;
    EXPECT_EQ(s->sigmas()[i + 1], rows[i].sigma_next) << n << ":" << i;
    EXPECT_NEAR(s->timesteps()[i], rows[i].c_noise, 1e-11) << n << ":" << i;
  }
}

TEST(AnimateLcmSampler, Schedules8And4MatchSpecTables) {
  expect_lcm_table(8, kLcm8);
  expect_lcm_table(4, kLcm4);
  auto s = lcm();
  EXPECT_STREQ(s->name(), "animatelcm");
  EXPECT_EQ(s->default_steps(), 8);
  s->set_timesteps(8);
  EXPECT_NEAR(s->init_noise_sigma(), 700.0007142853499, 1e-12);
  EXPECT_EQ(float(s->init_noise_sigma()), 700.000732421875f);
  // c_noise stays double: 0.25 ln(700) is not a float32 value.
  EXPECT_NE(double(float(s->timesteps()[0])), s->timesteps()[0]);
}

TEST(AnimateLcmSampler, ScalingsMatchSpecValues) {
  // scheduler.md §3.4: (sigma, c_in, c_skip, c_out) in float32.
  struct Row {
    int n, i;
    float sigma, c_in, c_skip, c_out;
  };
  const Row rows[] = {{4, 1, 128.56369f, 0.00777801033f, 6.04974484e-05f, -0.999969721f},
                      {4, 2, 13.6784439f, 0.0729131401f, 0.00531632593f, -0.997338295f},
                      {4, 3, 0.496878415f, 0.895542562f, 0.801996529f, -0.444975764f},
                      {8, 7, 0.0397536904f, 0.999210715f, 0.998422146f, -0.039722316f}};
  auto s = lcm();
  for (const Row& r : rows) {
    s->set_timesteps(r.n);
    ASSERT_EQ(s->sigmas()[r.i], r.sigma);
    float one = 1.0f, zero = 0.0f, z = 0.0f, cin, c_out, c_skip;
    s->scale_model_input(&one, &cin, 1, r.i);
    EXPECT_NEAR(cin, r.c_in, 1e-7 * r.c_in);
    // With zero noise, denoised = c_out * v + c_skip * x exactly picks out each scaling.
    s->step(&one, &zero, &z, &c_out, 1, r.i);
    s->step(&zero, &one, &z, &c_skip, 1, r.i);
    EXPECT_NEAR(c_out, r.c_out, 1.5e-7 * std::fabs(r.c_out)) << r.sigma;
    EXPECT_NEAR(c_skip, r.c_skip, 1.5e-7 * r.c_skip) << r.sigma;
  }
}

TEST(AnimateLcmSampler, StepRenoisesToNextSigma) {
  auto s = lcm();
  s->set_timesteps(8);
  const float x[3] = {1000.0f, -20.0f, 0.5f}, v[3] = {0.3f, -1.0f, 2.0f}, z[3] = {0.7f, -1.2f, 0.0f};
  for (int i = 0; i < 8; ++i) {
    ASSERT_TRUE(s->step_needs_noise(i));
    float out[3];
    s->step(v, x, z, out, 3, i);
    const double sig = s->sigmas()[i], next = s->sigmas()[i + 1];
    for (int k = 0; k < 3; ++k) {
      const double den = -sig / std::sqrt(sig * sig + 1) * v[k] + x[k] / (sig * sig + 1);
      const double want = den + z[k] * next;
      EXPECT_NEAR(out[k], want, 2e-6 * (std::fabs(want) + std::fabs(x[k]) * 1e-2 + 1e-3)) << i << "," << k;
    }
  }
  // Last step: sigma_next = 0, so the noise has no effect.
  float a[3], b[3];
  const float other[3] = {5.0f, 5.0f, 5.0f};
  s->step(v, x, z, a, 3, 7);
  s->step(v, x, other, b, 3, 7);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(a[k], b[k]);
}

TEST(AnimateLcmSampler, AnyStepCountProperties) {
  auto s = lcm();
  const double lo = std::pow(0.002, 1 / 7.0), hi = std::pow(700.0, 1 / 7.0);
  for (int n = 1; n <= 40; ++n) {
    s->set_timesteps(n);
    ASSERT_EQ(s->num_steps(), n);
    EXPECT_EQ(s->sigmas()[0], 700.0f);
    EXPECT_EQ(s->sigmas()[n], 0.0f);
    // Smallest sigma sits at ramp (n-1)*(40 div n)/39, not at sigma_min (unless n = 40).
    const double ramp = double((n - 1) * (40 / n)) / 39.0;
    EXPECT_EQ(s->sigmas()[n - 1], float(std::pow(hi + ramp * (lo - hi), 7.0))) << n;
    for (int i = 0; i < n; ++i) EXPECT_GT(s->sigmas()[i], s->sigmas()[i + 1]) << n << ":" << i;
    EXPECT_EQ(s->step_needs_noise(0), n > 1);
  }
  s->set_timesteps(40);
  EXPECT_EQ(s->sigmas()[39], 0.002f);
  EXPECT_THROW(s->set_timesteps(41), Error);
  EXPECT_THROW(s->set_timesteps(0), Error);
}

TEST(AnimateLcmSampler, SingleStepNeedsNoNoise) {
  auto s = lcm();
  s->set_timesteps(1);
  const float x = 3.0f, v = 0.5f;
  float out;
  s->step(&v, &x, nullptr, &out, 1, 0);
  const double sig = 700.0;
  EXPECT_NEAR(out, -sig / std::sqrt(sig * sig + 1) * v + x / (sig * sig + 1), 1e-6);
}

TEST(Sampler, TensorApiChecksShapesAndSteps) {
  auto s = lcm();
  EXPECT_THROW(s->scale_model_input(Tensor::zeros({2, 3}), 0), Error);  // set_timesteps not called
  s->set_timesteps(4);
  Tensor x = Tensor::full({2, 3}, 2.0f), v = Tensor::zeros({2, 3}), z = Tensor::zeros({2, 3});
  EXPECT_THROW(s->step(v, 0, x), Error);                   // needs noise
  EXPECT_THROW(s->step(Tensor::zeros({3, 2}), 0, x, &z), Error);  // shape mismatch
  EXPECT_THROW(s->step(v, 4, x, &z), Error);               // step out of range
  Tensor y = s->step(v, 3, x, &z);
  EXPECT_EQ(y.shape(), x.shape());
  Tensor x0 = s->init_latents(Tensor::full({2}, 1.0f));
  EXPECT_EQ(x0[0], 700.000732421875f);
}

// ---- config errors ----

class ConfigErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("egopd_sched_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const nlohmann::json& j) {
    const std::string p = (dir_ / "scheduler_config.json").string();
    std::ofstream(p) << dump_json(j);
    return p;
  }
  // The error of loading j, or "" if it loads.
  std::string error_of(const nlohmann::json& j) {
    try {
      load_sampler(write(j));
    } catch (const Error& e) {
      return e.what();
    }
    return "";
  }
  static nlohmann::json euler_cfg() {
    return {{"_class_name", "EulerDiscreteScheduler"}, {"prediction_type", "v_prediction"},
            {"timestep_type", "continuous"},           {"timestep_spacing", "leading"},
            {"use_karras_sigmas", true},               {"sigma_min", 0.002},
            {"sigma_max", 700.0}};
  }
  static nlohmann::json lcm_cfg() {
    return {{"_class_name", "AnimateLCMSVDStochasticIterativeScheduler"},
            {"num_train_timesteps", 40},
            {"sigma_min", 0.002},
            {"sigma_max", 700.0},
            {"sigma_data", 1.0},
            {"clip_denoised", false}};
  }
  fs::path dir_;
};

TEST_F(ConfigErrors, MinimalConfigsLoadFromFileDirAndModelDir) {
  EXPECT_EQ(error_of(euler_cfg()), "");
  EXPECT_EQ(error_of(lcm_cfg()), "");
  EXPECT_STREQ(load_sampler(dir_.string())->name(), "animatelcm");
  fs::create_directories(dir_ / "model" / "scheduler");
  fs::rename(dir_ / "scheduler_config.json", dir_ / "model" / "scheduler" / "scheduler_config.json");
  EXPECT_STREQ(load_sampler((dir_ / "model").string())->name(), "animatelcm");
}

TEST_F(ConfigErrors, NameFileAndField) {
  auto expect_err = [&](nlohmann::json j, const std::string& field) {
    const std::string e = error_of(j);
    EXPECT_NE(e.find("scheduler_config.json"), std::string::npos) << e;
    EXPECT_NE(e.find("'" + field + "'"), std::string::npos) << e;
    EXPECT_EQ(e.find('\n'), std::string::npos) << e;
  };
  auto j = euler_cfg();
  j["_class_name"] = "DDIMScheduler";
  expect_err(j, "_class_name");
  j = euler_cfg();
  j.erase("_class_name");
  expect_err(j, "_class_name");
  j = euler_cfg();
  j["prediction_type"] = "epsilon";
  expect_err(j, "prediction_type");
  j = euler_cfg();
  j["use_karras_sigmas"] = false;
  expect_err(j, "use_karras_sigmas");
  j = euler_cfg();
  j["timestep_type"] = "discrete";
  expect_err(j, "timestep_type");
  j = euler_cfg();
  j["timestep_spacing"] = "trailing";
  expect_err(j, "timestep_spacing");
  j = euler_cfg();
  j["final_sigmas_type"] = "sigma_min";
  expect_err(j, "final_sigmas_type");
  j = euler_cfg();
  j.erase("sigma_max");
  expect_err(j, "sigma_max");
  j = lcm_cfg();
  j.erase("sigma_data");
  expect_err(j, "sigma_data");
  j = lcm_cfg();
  j.erase("clip_denoised");
  expect_err(j, "clip_denoised");
  j = lcm_cfg();
  j["sigma_max"] = "700";
  expect_err(j, "sigma_max");
}

TEST_F(ConfigErrors, MissingFileIsOneLine) {
  try {
    load_sampler((dir_ / "nowhere").string());
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nowhere"), std::string::npos);
  }
}

TEST_F(ConfigErrors, ClipDenoisedClamps) {
  auto j = lcm_cfg();
  j["clip_denoised"] = true;
  auto s = load_sampler(write(j));
  s->set_timesteps(4);
  const float x = 0.0f, v = -50.0f, z = 0.0f;  // denoised = c_out * v ~ +50 -> clamped to 1
  float out;
  s->step(&v, &x, &z, &out, 1, 3);
  EXPECT_EQ(out, 1.0f);
}

}  // namespace
}  // namespace egopd
