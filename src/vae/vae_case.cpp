// Golden-case runners of the temporal VAE (components vae_encode and vae_decode).
#include "core/golden.h"
#include "vae/temporal_vae.h"

namespace egopd {

// image [N,3,H,W] -> latent_mean, latent_logvar [N,4,H/8,W/8] (mode() = mean, no scaling factor).
CaseOutputs run_vae_encode_case(const GoldenCase& c) {
  TemporalVAE vae(c.model_dir());
  CaseOutputs out;
  Tensor logvar;
  out.tensors["latent_mean"] = vae.encode_mean(c.input("image"), &logvar);
  out.tensors["latent_logvar"] = logvar;
  return out;
}

// z [B*F,4,h,w], args.num_frames = F -> sample [B*F,3,H,W]: the decoder called directly (no scaling); with
// args.decode_chunk_size, chunked decoding as the pipeline does it.
CaseOutputs run_vae_decode_case(const GoldenCase& c) {
  TemporalVAE vae(c.model_dir());
  const int64_t frames = c.args.get_int("num_frames");
  CaseOutputs out;
  if (c.args.has("decode_chunk_size"))
    out.tensors["sample"] = vae.decode(c.input("z"), frames, c.args.get_int("decode_chunk_size"));
  else
    out.tensors["sample"] = vae.decode_frames(c.input("z"), frames);
  return out;
}

}  // namespace egopd
