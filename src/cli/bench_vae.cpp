// `egopd bench vae_encode` / `egopd bench vae_decode`: the real-size SVD-xt temporal VAE (vae.md §1) with
// deterministic random weights (written once into the cache folder), on a clip of --frames frames at --size x --size
// pixels.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/json_text.h"
#include "core/kernels/kernel_profile.h"
#include "core/memory.h"
#include "core/synthetic_weights.h"
#include "core/threading.h"
#include "vae/temporal_vae.h"
#include "vae/vae_random.h"

namespace egopd {
namespace fs = std::filesystem;

namespace {

struct VaeBenchOptions {
  DType dtype = DType::F16;
  int64_t frames = 16, size = 256, chunk = 0, repeat = 1, warmup = 0;
  bool json = false;
  bool profile_kernels = false;
};

VaeBenchOptions read_options(const Args& a, const std::string& target, bool decode) {
  VaeBenchOptions o;
  const std::string config = a.get("config", "svd-xt");
  o.frames = a.get_int("frames", 16);
  o.size = a.get_int("size", 256);
  o.dtype = parse_weight_dtype(a.get("dtype", "f16"), "dtype");
  if (decode) o.chunk = a.get_int("decode-chunk", 0);
  o.repeat = a.get_int("repeat", 1);
  o.warmup = a.get_int("warmup", 0);
  o.json = a.flag("json");
  o.profile_kernels = a.flag("kernel-profile");
  a.finish();
  if (config != "svd-xt") throw Error("bench " + target + ": --config must be svd-xt (got '" + config + "')");
  if (o.frames < 1 || o.frames > 1024) throw Error("bench " + target + ": --frames must be between 1 and 1024");
  if (o.size < 8 || o.size % 8 != 0) throw Error("bench " + target + ": --size must be a positive multiple of 8");
  if (o.chunk < 0) throw Error("bench " + target + ": --decode-chunk must be positive (0 = all frames)");
  if (o.repeat < 1 || o.repeat > 100) throw Error("bench " + target + ": --repeat must be between 1 and 100");
  if (o.warmup < 0 || o.warmup > 100) throw Error("bench " + target + ": --warmup must be between 0 and 100");
  return o;
}

// bench-vae-<id> in the benchmarks' cache folder (cached_bench_folder; id: a hash of the config, the parameter list,
// dtype, seed and the generator's values).
std::string vae_model_dir(const VaeConfig& cfg, DType dtype) {
  constexpr uint64_t kSeed = 1234;
  const std::string weights_id = synthetic_weights_id(vae_parameter_shapes(cfg), dtype, kSeed);
  const std::string name = "bench-vae-" + hex16(fnv1a(dump_json(cfg.to_json()), fnv1a(weights_id)));
  return cached_bench_folder(name, "config.json", [&](const std::string& tmp) {
    std::fprintf(stderr, "bench vae: writing a random %s VAE (%s)\n", dtype_name(dtype), name.c_str());
    write_random_vae(tmp, cfg, dtype, kSeed);
  });
}

Tensor pattern(const Shape& s, float amp) {  // deterministic values in [-amp, amp]
  Tensor t(s);
  for (int64_t i = 0; i < t.numel(); ++i) t[i] = amp * (float((i * 7919) % 2001) / 1000.0f - 1.0f);
  return t;
}

void describe_output(const Tensor& y, BenchReport& r) {
  double sq = 0;
  bool finite = true;
  for (int64_t i = 0; i < y.numel(); ++i) {
    finite = finite && std::isfinite(y[i]);
    sq += double(y[i]) * y[i];
  }
  r.extra["output_shape"] = y.shape().vec();
  r.extra["output_finite"] = finite;
  r.extra["output_rms"] = std::sqrt(sq / double(std::max<int64_t>(1, y.numel())));
}

int run_vae_bench(const Args& a, bool decode) {
  const std::string target = decode ? "vae_decode" : "vae_encode";
  const VaeBenchOptions o = read_options(a, target, decode);
  const VaeConfig cfg = VaeConfig::svd_xt();
  TemporalVAE vae(vae_model_dir(cfg, o.dtype));
  const int64_t latent = o.size / cfg.spatial_factor();

  BenchReport r;
  r.target = target;
  r.threads = num_threads();
  r.extra["config"] = "svd-xt";
  r.extra["dtype"] = dtype_name(o.dtype);
  r.extra["frames"] = o.frames;
  r.extra["size"] = o.size;
  r.extra["repeat"] = o.repeat;
  r.extra["weights_bytes"] = vae.weight_bytes();
  r.extra["rss_before_run_bytes"] = current_rss_bytes();
  r.extra["warmup_calls"] = o.warmup;
  Tensor y;
  const int64_t chunk = o.chunk > 0 ? o.chunk : o.frames;
  const Tensor input = decode ? pattern(Shape{o.frames, cfg.latent_channels, latent, latent}, 1.0f)
                              : pattern(Shape{o.frames, cfg.in_channels, o.size, o.size}, 1.0f);
  const auto call = [&] { y = decode ? vae.decode_latents(input, o.frames, chunk) : vae.encode_mean(input); };
  // Untimed calls first when asked (the first call also faults the mapped weights and the scratch in), outside the
  // kernel profile.
  warm_up(target, o.warmup, call);
  set_kernel_profiling(o.profile_kernels);
  const CallTimes t = median_call_times(o.repeat, false, call);
  r.seconds = t.wall, r.cpu_seconds = t.cpu;
  if (decode) {
    r.gflop = vae_decode_flop(cfg, o.frames, latent, latent) * 1e-9;
    r.extra["decode_chunk"] = chunk;
  } else {
    r.gflop = vae_encode_flop(cfg, o.frames, o.size, o.size) * 1e-9;
  }
  describe_output(y, r);
  if (o.profile_kernels) add_kernel_profile(r, o.repeat);
  r.extra["peak_rss_above_weights_bytes"] = int64_t(peak_rss_bytes()) - int64_t(vae.weight_bytes());
  print_bench_report(r, o.json);
  return 0;
}

}  // namespace

int bench_vae_encode(const Args& a) { return run_vae_bench(a, false); }
int bench_vae_decode(const Args& a) { return run_vae_bench(a, true); }

}  // namespace egopd
