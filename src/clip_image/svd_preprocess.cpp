#include "clip_image/svd_preprocess.h"

#include <algorithm>
#include <cmath>

#include "core/config.h"
#include "core/error.h"

namespace egopd {

ClipImageNormalization ClipImageNormalization::load(const std::string& path) {
  const Config c = Config::load(path);
  ClipImageNormalization n;
  n.mean.clear();
  n.std.clear();
  for (double v : c.get_double_list("image_mean")) n.mean.push_back(float(v));
  for (double v : c.get_double_list("image_std")) {
    if (!(v > 0)) c.fail("image_std", "every value must be positive");
    n.std.push_back(float(v));
  }
  if (n.mean.empty() || n.mean.size() != n.std.size())
    c.fail("image_std", "image_mean and image_std must have the same non-zero length");
  return n;
}

std::vector<double> antialias_kernel(double factor) {
  const double sigma = std::max((factor - 1.0) / 2.0, 0.001);
  int64_t k = int64_t(std::max(4.0 * sigma, 3.0));  // int(): truncation toward zero
  if (k % 2 == 0) ++k;
  std::vector<double> g(static_cast<size_t>(k));
  double sum = 0;
  for (int64_t i = 0; i < k; ++i) {
    const double p = double(i - k / 2);
    g[size_t(i)] = std::exp(-p * p / (2.0 * sigma * sigma));
    sum += g[size_t(i)];
  }
  for (double& v : g) v /= sum;
  return g;
}

namespace {

// Reflect an index into [0, n) without repeating the edge (valid for -n < i < 2n-1).
int64_t reflect(int64_t i, int64_t n) {
  if (i < 0) return -i;
  if (i >= n) return 2 * (n - 1) - i;
  return i;
}

// One 1-D "valid" correlation over the reflect-padded axis: `count` lines of length n with stride `step` between
// consecutive elements of a line; line l starts at base(l).
void blur_axis(const double* src, double* dst, int64_t n, const std::vector<double>& k, int64_t step,
               const std::vector<int64_t>& line_starts) {
  const int64_t r = int64_t(k.size()) / 2;
  for (int64_t start : line_starts)
    for (int64_t i = 0; i < n; ++i) {
      double acc = 0;
      for (int64_t j = 0; j < int64_t(k.size()); ++j) acc += k[size_t(j)] * src[start + reflect(i + j - r, n) * step];
      dst[start + i * step] = acc;
    }
}

// Keys cubic convolution, A = -0.75 (PyTorch upsample_bicubic2d).
constexpr double kCubicA = -0.75;
double cubic_k1(double u) { return ((kCubicA + 2) * u - (kCubicA + 3)) * u * u + 1; }                    // |u| <= 1
double cubic_k2(double u) { return ((kCubicA * u - 5 * kCubicA) * u + 8 * kCubicA) * u - 4 * kCubicA; }  // 1<|u|<2

// Taps and weights of every output index along one axis.
struct CubicAxis {
  std::vector<int64_t> tap;  // [m, 4] clamped source indices
  std::vector<double> w;     // [m, 4]
};

CubicAxis cubic_axis(int64_t n, int64_t m) {
  CubicAxis a;
  a.tap.resize(size_t(4 * m));
  a.w.resize(size_t(4 * m));
  const double scale = m > 1 ? double(n - 1) / double(m - 1) : 0.0;
  for (int64_t d = 0; d < m; ++d) {
    const double src = scale * double(d);
    const double f = std::floor(src);
    const int64_t i0 = int64_t(f);
    const double t = src - f;
    const double w[4] = {cubic_k2(t + 1), cubic_k1(t), cubic_k1(1 - t), cubic_k2(2 - t)};
    for (int64_t j = 0; j < 4; ++j) {
      a.tap[size_t(4 * d + j)] = std::clamp<int64_t>(i0 - 1 + j, 0, n - 1);
      a.w[size_t(4 * d + j)] = w[j];
    }
  }
  return a;
}

}  // namespace

std::vector<double> blur_reflect(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w,
                                 const std::vector<double>& kx, const std::vector<double>& ky) {
  EGOPD_CHECK(int64_t(x.size()) == planes * h * w, "blur input size");
  if (kx.size() % 2 == 0 || ky.size() % 2 == 0) throw Error("blur: kernel sizes must be odd");
  if (int64_t(kx.size()) / 2 >= w || int64_t(ky.size()) / 2 >= h)
    throw Error("blur: reflect padding of " + std::to_string(std::max(kx.size(), ky.size()) / 2) +
                " needs an image larger than " + std::to_string(h) + "x" + std::to_string(w));
  std::vector<double> tmp(x.size()), out(x.size());
  std::vector<int64_t> rows, cols;
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t i = 0; i < h; ++i) rows.push_back((p * h + i) * w);
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t j = 0; j < w; ++j) cols.push_back(p * h * w + j);
  blur_axis(x.data(), tmp.data(), w, kx, 1, rows);    // along the width
  blur_axis(tmp.data(), out.data(), h, ky, w, cols);  // then along the height
  return out;
}

std::vector<double> bicubic_align_corners(const std::vector<double>& x, int64_t planes, int64_t h, int64_t w,
                                          int64_t out_h, int64_t out_w) {
  EGOPD_CHECK(int64_t(x.size()) == planes * h * w, "bicubic input size");
  if (h < 1 || w < 1 || out_h < 1 || out_w < 1) throw Error("bicubic resize: empty image");
  const CubicAxis ax = cubic_axis(w, out_w), ay = cubic_axis(h, out_h);
  // Along x for every source row: [planes, h, w] -> [planes, h, out_w]; then along y.
  std::vector<double> rows(size_t(planes * h * out_w));
  for (int64_t r = 0; r < planes * h; ++r)
    for (int64_t d = 0; d < out_w; ++d) {
      double acc = 0;
      for (int64_t j = 0; j < 4; ++j) acc += ax.w[size_t(4 * d + j)] * x[size_t(r * w + ax.tap[size_t(4 * d + j)])];
      rows[size_t(r * out_w + d)] = acc;
    }
  std::vector<double> out(size_t(planes * out_h * out_w));
  for (int64_t p = 0; p < planes; ++p)
    for (int64_t d = 0; d < out_h; ++d)
      for (int64_t c = 0; c < out_w; ++c) {
        double acc = 0;
        for (int64_t j = 0; j < 4; ++j)
          acc += ay.w[size_t(4 * d + j)] * rows[size_t((p * h + ay.tap[size_t(4 * d + j)]) * out_w + c)];
        out[size_t((p * out_h + d) * out_w + c)] = acc;
      }
  return out;
}

Tensor resize_with_antialiasing(const Tensor& x, int64_t out_h, int64_t out_w) {
  if (x.ndim() != 4) throw Error("resize: image must be [B,C,H,W], got " + x.shape().str());
  const int64_t b = x.dim(0), c = x.dim(1), h = x.dim(2), w = x.dim(3);
  const std::vector<double> kx = antialias_kernel(double(w) / double(out_w));
  const std::vector<double> ky = antialias_kernel(double(h) / double(out_h));
  std::vector<double> src(x.data(), x.data() + x.numel());
  const std::vector<double> blurred = blur_reflect(src, b * c, h, w, kx, ky);
  const std::vector<double> resized = bicubic_align_corners(blurred, b * c, h, w, out_h, out_w);
  Tensor out({b, c, out_h, out_w});
  for (int64_t i = 0; i < out.numel(); ++i) out[i] = float(resized[size_t(i)]);
  return out;
}

Tensor svd_clip_preprocess(const Tensor& image, const ClipImageNormalization& norm, int64_t size) {
  if (image.ndim() != 4 || image.dim(1) != int64_t(norm.mean.size()))
    throw Error("CLIP preprocessing: image must be [B," + std::to_string(norm.mean.size()) + ",H,W], got " +
                image.shape().str());
  Tensor x = resize_with_antialiasing(image, size, size);
  const int64_t b = x.dim(0), c = x.dim(1), plane = size * size;
  for (int64_t i = 0; i < b; ++i)
    for (int64_t ch = 0; ch < c; ++ch) {
      float* p = x.data() + (i * c + ch) * plane;
      const float mean = norm.mean[size_t(ch)], std = norm.std[size_t(ch)];
      for (int64_t t = 0; t < plane; ++t) p[t] = ((p[t] + 1.0f) / 2.0f - mean) / std;
    }
  return x;
}

}  // namespace egopd
