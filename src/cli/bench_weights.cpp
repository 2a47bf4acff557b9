// Synthetic weights of the component benches (unet, clip_image, clip_text), written once into the cache folder and
// reused: a real-size file takes longer to write than a run takes.
#include <unistd.h>

#include <cstdio>
#include <filesystem>

#include "cli/commands.h"
#include "core/atomic_file.h"
#include "core/synthetic_weights.h"
#include "pipeline/predict_run.h"

namespace egopd {
namespace fs = std::filesystem;

std::shared_ptr<const WeightMap> bench_synthetic_weights(const std::string& bench, const std::string& label,
                                                         const std::vector<std::pair<std::string, Shape>>& params,
                                                         DType dtype) {
  constexpr uint64_t kSeed = 1234;
  const std::string root = cache_root();
  const bool cached = !root.empty();
  const std::string name = cached ? "bench-" + bench + "-" + synthetic_weights_id(params, dtype, kSeed)
                                  : "egopd-bench-" + bench + "-" + std::to_string(::getpid());
  const std::string path = ((cached ? fs::path(root) : fs::temp_directory_path()) / (name + ".safetensors")).string();
  if (cached) remove_abandoned_temporaries(path);  // left by a killed bench
  if (!fs::exists(path)) {
    std::fprintf(stderr, "bench %s: writing %zu random %s tensors to %s\n", bench.c_str(), params.size(),
                 dtype_name(dtype), path.c_str());
    write_synthetic_safetensors(path, params, dtype, kSeed);  // atomic: never a half-written cache file
  }
  auto weights = std::make_shared<const WeightMap>(WeightMap::load_file(path, label));
  if (!cached) std::remove(path.c_str());  // the mapping keeps the data readable
  return weights;
}

std::string cached_bench_folder(const std::string& name, const std::string& marker,
                                const std::function<void(const std::string& dir)>& fill) {
  std::string root = cache_root();
  if (root.empty()) root = (fs::temp_directory_path() / "egopd-cache").string();
  const std::string dir = (fs::path(root) / name).string();
  remove_abandoned_temporaries(dir);  // left by a killed bench (gigabytes at real size)
  if (fs::exists(fs::path(dir) / marker)) return dir;
  AtomicDir tmp(dir, marker);
  fill(tmp.path());
  if (!fs::exists(fs::path(dir) / marker)) tmp.commit();  // else another bench finished first: use its folder
  return dir;
}

}  // namespace egopd
