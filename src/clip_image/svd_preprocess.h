#pragma once
// SVD's preparation of an image for the CLIP vision tower (clip.md §4): anti-aliasing Gaussian blur (reflect
// padding) + bicubic resize (align_corners=True, A = -0.75, source coordinates in double) to 224x224, then
// (x+1)/2 and the CLIP per-channel mean/std. Blur and resize are evaluated in double.
#include <string>
#include <vector>

#include "core/tensor.h"

namespace egopd {

// image_mean / image_std of feature_extractor/preprocessor_config.json (CLIPImageProcessor).
struct ClipImageNormalization {
  std::vector<float> mean = {0.48145466f, 0.4578275f, 0.40821073f};
  std::vector<float> std = {0.26862954f, 0.26130258f, 0.27577711f};
  static ClipImageNormalization load(const std::string& preprocessor_config_path);
};

// The separable Gaussian blur's 1-D kernel for a down-scaling factor (input/output length):
// sigma = max((factor-1)/2, 0.001), size int(max(4 sigma, 3)) made odd, taps normalised to sum 1.
std::vector<double> antialias_kernel(double factor);

// Separable blur of x [planes, h, w]: kx along the width first, then ky along the height; each pass uses reflect
// padding of (k-1)/2 (index -1 -> 1, n -> n-2). Odd kernel sizes; (k-1)/2 must be < the axis length.
std::vector<double> blur_reflect(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w,
                                 const std::vector<double>& kx, const std::vector<double>& ky);

// Bicubic interpolation with align_corners=True: x [planes, h, w] -> [planes, out_h, out_w].
std::vector<double> bicubic_align_corners(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w,
                                          int64_t out_h, int64_t out_w);

// diffusers' _resize_with_antialiasing: x [B, C, H, W] -> [B, C, out_h, out_w] (blur then bicubic), float32 out.
Tensor resize_with_antialiasing(const Tensor& x, int64_t out_h, int64_t out_w);

// The full path: image [B, C, H, W] in [-1, 1] -> pixel_values [B, C, size, size]. C must match mean/std.
Tensor svd_clip_preprocess(const Tensor& image, const ClipImageNormalization& norm, int64_t size = 224);

}  // namespace egopd
