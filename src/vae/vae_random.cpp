#include "vae/vae_random.h"

#include <filesystem>

#include "core/atomic_file.h"
#include "core/json_text.h"
#include "core/safetensors.h"
#include "core/synthetic_weights.h"

namespace egopd {

void write_random_vae(const std::string& dir, const VaeConfig& cfg, DType dtype, uint64_t seed) {
  const std::filesystem::path d(dir);
  std::filesystem::create_directories(d);
  write_file_atomic((d / "config.json").string(), dump_json(cfg.to_json(), 2) + "\n");
  write_synthetic_safetensors((d / "diffusion_pytorch_model.safetensors").string(), vae_parameter_shapes(cfg), dtype,
                              seed);
}

}  // namespace egopd
