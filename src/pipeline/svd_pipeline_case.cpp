// Golden-case runner for component "svd_pipeline": the stock SVD image-to-video sampling loop (scheduler.md §2)
// with CLIP + VAE conditioning, frame-wise classifier-free guidance and the temporal VAE decode.
#include <algorithm>
#include <cstring>
#include <filesystem>

#include "clip_image/clip_vision.h"
#include "clip_image/svd_preprocess.h"
#include "core/error.h"
#include "core/golden.h"
#include "scheduler/guidance.h"
#include "scheduler/sampler.h"
#include "unet3d/unet.h"
#include "vae/temporal_vae.h"

namespace egopd {
namespace fs = std::filesystem;

CaseOutputs run_svd_pipeline_case(const GoldenCase& c) {
  const fs::path dir = c.model_dir();
  const int64_t steps = c.args.get_int("num_inference_steps");
  const float min_g = float(c.args.get_double("min_guidance_scale")), max_g = float(c.args.get_double("max_guidance_scale"));
  const double fps = c.args.get_double("fps"), motion = c.args.get_double("motion_bucket_id");
  const float noise_aug = float(c.args.get_double("noise_aug_strength"));
  const int64_t F = c.args.get_int("num_frames"), chunk = c.args.get_int("decode_chunk_size", F);
  const Tensor& image = c.input("image");
  const int64_t H = image.dim(2), W = image.dim(3);

  // CLIP branch: image_embeddings [1, 1, proj]
  auto clip = ClipVisionModelWithProjection::load_dir((dir / "image_encoder").string());
  const auto norm = ClipImageNormalization::load((dir / "feature_extractor" / "preprocessor_config.json").string());
  Tensor embeds = clip.forward(svd_clip_preprocess(image, norm, clip.config().image_size)).image_embeds;
  const int64_t D = embeds.dim(1);
  Tensor image_embeddings = embeds.reshaped({1, 1, D});

  // VAE branch: mode() of the noise-augmented image, unscaled, repeated over the frames
  TemporalVAE vae((dir / "vae").string());
  Tensor aug = image.clone();
  const Tensor& aug_noise = c.input("aug_noise");
  for (int64_t i = 0; i < aug.numel(); ++i) aug[i] = image[i] + noise_aug * aug_noise[i];
  Tensor image_latents = vae.encode_mean(aug);  // [1, 4, h, w]
  const int64_t lc = image_latents.dim(1), h = image_latents.dim(2), w = image_latents.dim(3);

  UNetSpatioTemporal unet((dir / "unet").string());
  auto sampler = load_sampler((dir / "scheduler").string());
  sampler->set_timesteps(int(steps));
  const std::vector<float> g = frame_guidance_scales(min_g, max_g, F);
  const bool cfg = guidance_enabled(max_g);
  const int64_t B = cfg ? 2 : 1;  // [uncond, cond]: the unconditional half has zero embeddings and latents

  Tensor ehs = Tensor::zeros({B, 1, D});
  std::memcpy(ehs.data() + (B - 1) * D, image_embeddings.data(), size_t(D) * sizeof(float));
  UNetConditioning cond = unet.prepare(ehs, nullptr);
  Tensor ids({B, 3});
  for (int64_t b = 0; b < B; ++b) ids[b * 3] = float(fps - 1), ids[b * 3 + 1] = float(motion), ids[b * 3 + 2] = noise_aug;

  Tensor x = sampler->init_latents(c.input("initial_latents_noise"));  // [1, F, 4, h, w]
  const int64_t frame = lc * h * w;
  Tensor per_step({steps, 1, F, lc, h, w});
  Tensor u = Tensor::zeros({B, F, 2 * lc, h, w});
  for (int64_t i = 0; i < steps; ++i) {
    Tensor xs = sampler->scale_model_input(x, int(i));
    // u[b, f] = [x_scaled[f], image_latents (0 for the unconditional half)]
    for (int64_t b = 0; b < B; ++b)
      for (int64_t f = 0; f < F; ++f) {
        float* dst = u.data() + (b * F + f) * 2 * frame;
        std::memcpy(dst, xs.data() + f * frame, size_t(frame) * sizeof(float));
        if (b == B - 1) std::memcpy(dst + frame, image_latents.data(), size_t(frame) * sizeof(float));
      }
    Tensor v = unet.forward(u, float(sampler->timesteps()[size_t(i)]), ids, cond);
    if (cfg) {
      Tensor vu = Tensor::view({1, F, lc, h, w}, v.data()), vc = Tensor::view({1, F, lc, h, w}, v.data() + F * frame);
      v = cfg_combine(vu, vc, g);
    }
    x = sampler->step(v, int(i), x);
    std::memcpy(per_step.data() + i * F * frame, x.data(), size_t(F * frame) * sizeof(float));
  }

  // decode: [F, 4, h, w] -> [F, 3, H, W]; frames [1, 3, F, H, W]; video = clamp(frames/2 + 0.5) as [1, F, 3, H, W]
  Tensor decoded = vae.decode_latents(x.reshaped({F, lc, h, w}), F, chunk);
  const int64_t C = decoded.dim(1);
  Tensor frames({1, C, F, H, W}), video({1, F, C, H, W});
  for (int64_t f = 0; f < F; ++f)
    for (int64_t ch = 0; ch < C; ++ch)
      for (int64_t p = 0; p < H * W; ++p) {
        const float val = decoded[(f * C + ch) * H * W + p];
        frames[(ch * F + f) * H * W + p] = val;
        video[(f * C + ch) * H * W + p] = std::clamp(val / 2.0f + 0.5f, 0.0f, 1.0f);
      }

  CaseOutputs out;
  out.tensors["image_embeddings"] = image_embeddings;
  out.tensors["image_latents"] = image_latents;
  out.tensors["latents_per_step"] = per_step;
  out.tensors["final_latents"] = x;
  out.tensors["frames"] = frames;
  out.tensors["video"] = video;
  return out;
}

}  // namespace egopd
