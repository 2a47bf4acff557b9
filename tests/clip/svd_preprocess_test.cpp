// SVD CLIP preprocessing against references written here: a direct 2-D (non-separable) evaluation of the blur and of
// the 16-tap bicubic formula of clip.md §4, in double, plus hand-derived kernels.
#include "clip_image/svd_preprocess.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "core/error.h"

namespace egopd {
namespace {

std::vector<double> random_image(int64_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> v(static_cast<size_t>(n));
  for (auto& x : v) x = u(rng);
  return v;
}

double cubic(double x) {  // Keys kernel, A = -0.75, as a function of the distance |x|
  const double a = -0.75, u = std::fabs(x);
  if (u <= 1) return (a + 2) * u * u * u - (a + 3) * u * u + 1;
  if (u < 2) return a * u * u * u - 5 * a * u * u + 8 * a * u - 4 * a;
  return 0;
}

// out(d_y, d_x) = sum over the 4x4 taps around the double source coordinate, taps clamped to the image.
std::vector<double> reference_bicubic(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w, int64_t oh,
                                      int64_t ow) {
  std::vector<double> out(static_cast<size_t>(planes * oh * ow));
  const double sy = oh > 1 ? double(h - 1) / double(oh - 1) : 0, sx = ow > 1 ? double(w - 1) / double(ow - 1) : 0;
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t dy = 0; dy < oh; ++dy)
      for (int64_t dx = 0; dx < ow; ++dx) {
        const double fy = sy * double(dy), fx = sx * double(dx);
        const int64_t iy = int64_t(std::floor(fy)), ix = int64_t(std::floor(fx));
        double acc = 0;
        for (int64_t ky = iy - 1; ky <= iy + 2; ++ky)
          for (int64_t kx = ix - 1; kx <= ix + 2; ++kx) {
            const int64_t cy = std::min(std::max<int64_t>(ky, 0), h - 1),
                          cx = std::min(std::max<int64_t>(kx, 0), w - 1);
            acc += cubic(fy - double(ky)) * cubic(fx - double(kx)) * x[size_t((p * h + cy) * w + cx)];
          }
        out[size_t((p * oh + dy) * ow + dx)] = acc;
      }
  return out;
}

// 2-D correlation with the outer product of the kernels, reflect-indexed.
std::vector<double> reference_blur(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w,
                                   const std::vector<double>& kx, const std::vector<double>& ky) {
  auto reflect = [](int64_t i, int64_t n) { return i < 0 ? -i : (i >= n ? 2 * n - 2 - i : i); };
  const int64_t rx = int64_t(kx.size()) / 2, ry = int64_t(ky.size()) / 2;
  std::vector<double> out(x.size());
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t i = 0; i < h; ++i)
      for (int64_t j = 0; j < w; ++j) {
        double acc = 0;
        for (int64_t a = -ry; a <= ry; ++a)
          for (int64_t b = -rx; b <= rx; ++b)
            acc += ky[size_t(a + ry)] * kx[size_t(b + rx)] *
                   x[size_t((p * h + reflect(i + a, h)) * w + reflect(j + b, w))];
        out[size_t((p * h + i) * w + j)] = acc;
      }
  return out;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  EXPECT_EQ(a.size(), b.size());
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

TEST(SvdPreprocess, AntialiasKernelsByHand) {
  // 256 -> 224: sigma = (256/224 - 1)/2 = 1/14, size 3, side taps exp(-98) (an identity in practice).
  std::vector<double> k = antialias_kernel(256.0 / 224.0);
  ASSERT_EQ(k.size(), 3u);
  const double side = std::exp(-98.0);
  EXPECT_NEAR(k[0], side / (1 + 2 * side), side * 1e-11);
  EXPECT_DOUBLE_EQ(k[1], 1.0 / (1 + 2 * side));
  // 512 -> 224: sigma = 9/14, int(max(4 sigma, 3)) = 3.
  k = antialias_kernel(512.0 / 224.0);
  ASSERT_EQ(k.size(), 3u);
  const double s = 9.0 / 14.0, e = std::exp(-1.0 / (2 * s * s));
  EXPECT_NEAR(k[0], e / (1 + 2 * e), 1e-15);
  EXPECT_NEAR(k[1], 1 / (1 + 2 * e), 1e-15);
  // factor 5: sigma 2, 4 sigma = 8 -> made odd: 9 taps, symmetric, summing to 1.
  k = antialias_kernel(5.0);
  ASSERT_EQ(k.size(), 9u);
  double sum = 0;
  for (size_t i = 0; i < 9; ++i) {
    sum += k[i];
    EXPECT_NEAR(k[i], k[8 - i], 1e-17);
  }
  EXPECT_NEAR(sum, 1.0, 1e-15);
  EXPECT_NEAR(k[4] / k[3], std::exp(1.0 / 8.0), 1e-14);
  // Up-scaling or equal size: sigma 0.001, 3 taps, exactly [0, 1, 0] in double.
  k = antialias_kernel(192.0 / 224.0);
  EXPECT_EQ(k, (std::vector<double>{0.0, 1.0, 0.0}));
}

TEST(SvdPreprocess, BlurMatchesDirect2D) {
  const int64_t planes = 2, h = 11, w = 17;
  const std::vector<double> x = random_image(planes * h * w, 1);
  const std::vector<double> kx = antialias_kernel(5.0), ky = antialias_kernel(512.0 / 224.0);  // 9 and 3 taps
  EXPECT_LT(max_abs_diff(blur_reflect(x, planes, h, w, kx, ky), reference_blur(x, planes, h, w, kx, ky)), 1e-14);
  // Reflect padding needs more pixels than the padding.
  EXPECT_THROW(blur_reflect(random_image(4 * 4, 2), 1, 4, 4, kx, ky), Error);
}

TEST(SvdPreprocess, BicubicMatchesSixteenTapReference) {
  struct Case {
    int64_t h, w, oh, ow;
  };
  for (const Case c : {Case{192, 256, 224, 224}, Case{256, 256, 224, 224}, Case{37, 53, 224, 224}, Case{5, 3, 9, 11},
                       Case{1, 7, 4, 3}, Case{6, 6, 1, 1}}) {
    const std::vector<double> x = random_image(3 * c.h * c.w, 7);
    const double diff =
        max_abs_diff(bicubic_align_corners(x, 3, c.h, c.w, c.oh, c.ow), reference_bicubic(x, 3, c.h, c.w, c.oh, c.ow));
    EXPECT_LT(diff, 1e-13) << c.h << "x" << c.w << " -> " << c.oh << "x" << c.ow;
  }
}

TEST(SvdPreprocess, BicubicHandValues) {
  // 1-D (one row) 4 -> 7: scale 0.5; output 1 sits at t = 0.5 between x0 and x1:
  // weights K2(1.5), K1(0.5), K1(0.5), K2(1.5) = -0.09375, 0.59375, 0.59375, -0.09375, tap -1 clamped to 0.
  const std::vector<double> x = {1, 2, 4, 8};
  const std::vector<double> y = bicubic_align_corners(x, 1, 1, 4, 1, 7);
  ASSERT_EQ(y.size(), 7u);
  EXPECT_DOUBLE_EQ(y[0], 1.0);
  EXPECT_DOUBLE_EQ(y[1], -0.09375 * 1 + 0.59375 * 1 + 0.59375 * 2 - 0.09375 * 4);
  EXPECT_DOUBLE_EQ(y[2], 2.0);
  EXPECT_DOUBLE_EQ(y[6], 8.0);
  // Same size: identity.
  EXPECT_EQ(bicubic_align_corners(x, 1, 2, 2, 2, 2), x);
}

TEST(SvdPreprocess, FullPathOnA224ImageIsOnlyTheNormalisation) {
  Tensor img({1, 3, 224, 224});
  const std::vector<double> v = random_image(img.numel(), 3);
  for (int64_t i = 0; i < img.numel(); ++i) img[i] = float(v[size_t(i)]);
  const ClipImageNormalization norm;
  const Tensor out = svd_clip_preprocess(img, norm);
  ASSERT_EQ(out.shape(), (Shape{1, 3, 224, 224}));
  for (int64_t c = 0; c < 3; ++c)
    for (int64_t i = 0; i < 224 * 224; ++i) {
      const int64_t k = c * 224 * 224 + i;
      const double want = ((double(img[k]) + 1) / 2 - double(norm.mean[size_t(c)])) / double(norm.std[size_t(c)]);
      ASSERT_NEAR(out[k], want, 1e-6) << k;
    }
}

TEST(SvdPreprocess, FullPathMatchesReferenceAt256) {
  const int64_t h = 256, w = 192;
  Tensor img({1, 3, h, w});
  const std::vector<double> v = random_image(img.numel(), 4);
  for (int64_t i = 0; i < img.numel(); ++i) img[i] = float(v[size_t(i)]);
  const std::vector<double> src(img.data(), img.data() + img.numel());
  const std::vector<double> ref = reference_bicubic(
      reference_blur(src, 3, h, w, antialias_kernel(double(w) / 224), antialias_kernel(double(h) / 224)), 3, h, w, 224,
      224);
  const ClipImageNormalization norm;
  const Tensor out = svd_clip_preprocess(img, norm);
  double worst = 0;
  for (int64_t c = 0; c < 3; ++c)
    for (int64_t i = 0; i < 224 * 224; ++i) {
      const int64_t k = c * 224 * 224 + i;
      const double want = ((ref[size_t(k)] + 1) / 2 - norm.mean[size_t(c)]) / norm.std[size_t(c)];
      worst = std::max(worst, std::fabs(out[k] - want));
    }
  EXPECT_LT(worst, 2e-6);
}

TEST(SvdPreprocess, ChannelCountMustMatchMeanStd) {
  EXPECT_THROW(svd_clip_preprocess(Tensor::zeros({1, 1, 32, 32}), ClipImageNormalization()), Error);
  EXPECT_THROW(svd_clip_preprocess(Tensor::zeros({3, 32, 32}), ClipImageNormalization()), Error);
}

}  // namespace
}  // namespace egopd
