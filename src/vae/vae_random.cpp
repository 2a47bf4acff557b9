#include "vae/vae_random.h"

#include <cmath>
#include <filesystem>
#include <vector>

#include "core/safetensors.h"

namespace egopd {

namespace {

// splitmix64: a fixed, portable stream of 64-bit values.
struct SplitMix {
  uint64_t s;
  uint64_t next() {
    uint64_t z = (s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
  }
  float uniform() { return float(double(next() >> 11) * (2.0 / 9007199254740992.0) - 1.0); }  // [-1, 1)
};

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

}  // namespace

void write_random_vae(const std::string& dir, const VaeConfig& cfg, DType dtype, uint64_t seed) {
  std::filesystem::create_directories(dir);
  write_file_atomic((std::filesystem::path(dir) / "config.json").string(), cfg.to_json().dump(2) + "\n");
  std::vector<TensorToWrite> out;
  uint64_t index = 0;
  for (const auto& [name, shape] : vae_parameter_shapes(cfg)) {
    SplitMix rng{seed * 0x100000001b3ull + index++};
    Tensor t(shape);
    const bool norm = name.find("norm") != std::string::npos;  // norm1/norm2/group_norm/conv_norm_out
    float lo = 0, amp = 0;
    if (ends_with(name, "mix_factor")) {
      amp = 1.0f;
    } else if (ends_with(name, ".bias")) {
      amp = 0.1f;
    } else if (norm) {
      lo = 1.0f, amp = 0.2f;
    } else {
      const int64_t fan_in = shape.numel() / shape[0];
      amp = float(std::sqrt(3.0 / double(fan_in)));  // variance 1/fan_in
    }
    for (int64_t i = 0; i < t.numel(); ++i) t[i] = lo + amp * rng.uniform();
    out.push_back(to_write(name, t, dtype));
  }
  write_safetensors((std::filesystem::path(dir) / "diffusion_pytorch_model.safetensors").string(), out);
}

}  // namespace egopd
