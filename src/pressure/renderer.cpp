#include "pressure/renderer.h"

#include <algorithm>
#include <cmath>

#include "core/error.h"
#include "pressure/normalization.h"

namespace egopd {

CanvasFit CanvasFit::fit(const std::vector<Point2>& outline, int size) {
  if (size < 8) throw Error("canvas size " + std::to_string(size) + " too small (need at least 8)");
  if (outline.empty()) throw Error("hand template: empty outline");
  double x0 = outline[0].x, x1 = x0, y0 = outline[0].y, y1 = y0;
  for (const auto& p : outline) {
    x0 = std::min(x0, p.x), x1 = std::max(x1, p.x);
    y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
  }
  const double wg = x1 - x0, hg = y1 - y0;
  if (!(std::max(wg, hg) > 0)) throw Error("hand template: outline has zero extent");
  CanvasFit f;
  f.margin = int(std::lround(size / 32.0));
  const double e = size - 1 - 2 * f.margin;
  f.scale = e / std::max(wg, hg);
  f.offset_x = f.margin + (e - f.scale * wg) / 2 - f.scale * x0;
  f.offset_y = f.margin + (e - f.scale * hg) / 2 - f.scale * y0;
  return f;
}

bool inside_polygon(const std::vector<Point2>& poly, double x, double y) {
  bool in = false;
  const size_t n = poly.size();
  for (size_t k = 0; k < n; ++k) {
    const Point2& a = poly[k];
    const Point2& b = poly[(k + 1) % n];
    if ((a.y > y) != (b.y > y) && x < a.x + (y - a.y) * (b.x - a.x) / (b.y - a.y)) in = !in;
  }
  return in;
}

RenderParams RenderParams::resolved(int size) const {
  RenderParams r = *this;
  const double k = size / 256.0;
  if (r.sigma_px <= 0) r.sigma_px = 6.0 * k;
  if (r.disk_radius_px <= 0) r.disk_radius_px = 3.0 * k;
  if (r.lambda <= 0) r.lambda = 1e-3 * k * k;
  if (!(r.eps >= 0)) throw Error("render parameters: eps must be >= 0");
  if (!(r.floor_percentile >= 0 && r.floor_percentile <= 100)) throw Error("render parameters: percentile outside [0, 100]");
  return r;
}

PressureRenderer::PressureRenderer(const HandTemplate& t, int size, RenderParams params)
    : size_(size), params_(params.resolved(size)), fit_(CanvasFit::fit(t.outline(), size)) {
  const int S = size_;
  for (const auto& p : t.outline()) outline_px_.push_back(fit_.to_canvas(p));
  for (const auto& s : t.sensors()) sensor_px_.push_back(fit_.to_canvas(s.grid));

  // V: pixel centres inside the fitted outline, row-major.
  pixel_to_v_.assign(size_t(S) * S, -1);
  for (int i = 0; i < S; ++i)
    for (int j = 0; j < S; ++j)
      if (inside_polygon(outline_px_, j, i)) {
        pixel_to_v_[size_t(i) * S + j] = int(hand_pixels_.size());
        hand_pixels_.push_back(i * S + j);
      }
  if (hand_pixels_.empty())
    throw Error(t.source() + ": the outline covers no pixel centre at canvas size " + std::to_string(S));
  for (size_t m = 0; m < sensor_px_.size(); ++m) {
    const int i = int(std::lround(sensor_px_[m].y)), j = int(std::lround(sensor_px_[m].x));
    if (!inside_polygon(outline_px_, sensor_px_[m].x, sensor_px_[m].y) || i < 0 || j < 0 || i >= S || j >= S ||
        pixel_to_v_[size_t(i) * S + j] < 0)
      warnings_.push_back(t.source() + ": sensor " + std::to_string(m) + " lies outside the hand mask V");
  }

  // Disk pixel sets for the read-out (§7 step 3).
  const double r = params_.disk_radius_px;
  disks_.resize(sensor_px_.size());
  for (size_t m = 0; m < sensor_px_.size(); ++m) {
    const Point2 c = sensor_px_[m];
    const int i0 = std::max(0, int(std::floor(c.y - r))), i1 = std::min(S - 1, int(std::ceil(c.y + r)));
    const int j0 = std::max(0, int(std::floor(c.x - r))), j1 = std::min(S - 1, int(std::ceil(c.x + r)));
    for (int i = i0; i <= i1; ++i)
      for (int j = j0; j <= j1; ++j) {
        const int v = pixel_to_v_[size_t(i) * S + j];
        const double dx = j - c.x, dy = i - c.y;
        if (v >= 0 && dx * dx + dy * dy <= r * r) disks_[m].push_back(v);
      }
  }

  // A: row-normalised Gaussian weights (§5).
  const int nv = num_hand_pixels(), M = num_sensors();
  const double inv2s2 = 1.0 / (2.0 * params_.sigma_px * params_.sigma_px);
  A_.resize(nv, M);
#pragma omp parallel for schedule(static)
  for (int v = 0; v < nv; ++v) {
    const double x = hand_pixels_[v] % S, y = hand_pixels_[v] / S;
    double sum = 0;
    for (int m = 0; m < M; ++m) {
      const double dx = x - sensor_px_[m].x, dy = y - sensor_px_[m].y;
      const double w = std::exp(-(dx * dx + dy * dy) * inv2s2);
      A_(v, m) = w;
      sum += w;
    }
    A_.row(v) /= (sum + params_.eps);
  }

  // Ridge inverse (§6) by Cholesky of the SPD matrix AᵀA + λI. Kept as K = (AᵀA + λI)⁻¹ (M × M): applying
  // Rg = K·Aᵀ as K·(Aᵀh) is the same product, and the M × M matrix Rg·A = K·AᵀA serves the read-out.
  Eigen::MatrixXd ata = Eigen::MatrixXd::Zero(M, M);
  ata.selfadjointView<Eigen::Lower>().rankUpdate(A_.transpose());  // symmetric: half the work of AᵀA
  ata = ata.selfadjointView<Eigen::Lower>();
  Eigen::MatrixXd reg = ata;
  reg.diagonal().array() += params_.lambda;
  Eigen::LLT<Eigen::MatrixXd> llt(reg);
  if (llt.info() != Eigen::Success) throw Error(t.source() + ": ridge system AᵀA + λI is not positive definite");
  K_ = llt.solve(Eigen::MatrixXd::Identity(M, M));
  RgA_ = llt.solve(ata);
}

Eigen::MatrixXd PressureRenderer::ridge_inverse() const { return K_ * A_.transpose(); }

std::vector<Point2> PressureRenderer::outline_canvas() const { return outline_px_; }

std::vector<double> PressureRenderer::render(const std::vector<double>& p) const {
  if (int(p.size()) != num_sensors())
    throw Error("render: got " + std::to_string(p.size()) + " taxels, template has " + std::to_string(num_sensors()));
  const Eigen::VectorXd h = A_ * Eigen::Map<const Eigen::VectorXd>(p.data(), p.size());
  std::vector<double> out(size_t(size_) * size_, 0.0);
  for (int v = 0; v < num_hand_pixels(); ++v) out[hand_pixels_[v]] = h[v];
  return out;
}

std::vector<double> PressureRenderer::ridge_solve(const std::vector<double>& heatmap) const {
  EGOPD_CHECK(heatmap.size() == size_t(size_) * size_, "heatmap size");
  Eigen::VectorXd h(num_hand_pixels());
  for (int v = 0; v < num_hand_pixels(); ++v) h[v] = heatmap[hand_pixels_[v]];
  const Eigen::VectorXd p = K_ * (A_.transpose() * h);
  return std::vector<double>(p.data(), p.data() + p.size());
}

std::vector<double> PressureRenderer::heatmap_from_image(const float* chw) const {
  const size_t n = size_t(size_) * size_;
  std::vector<double> h(n);
  for (size_t k = 0; k < n; ++k) {
    const double mean = (double(chw[k]) + double(chw[n + k]) + double(chw[2 * n + k])) / 3.0;
    // clamp and max would turn NaN into a silent 0 N: a broken model must fail instead.
    if (!std::isfinite(mean))
      throw Error("non-finite value in a generated heatmap (pixel " + std::to_string(k) + "); the model is broken");
    h[k] = std::clamp((mean + 1.0) / 2.0, 0.0, 1.0);
  }
  return h;
}

std::vector<double> PressureRenderer::percentile_floor(const std::vector<double>& h_raw) const {
  EGOPD_CHECK(h_raw.size() == size_t(size_) * size_, "heatmap size");
  std::vector<double> vals(num_hand_pixels());
  for (int v = 0; v < num_hand_pixels(); ++v) vals[v] = h_raw[hand_pixels_[v]];
  // Linear interpolation between order statistics (numpy's default percentile).
  const double pos = params_.floor_percentile / 100.0 * double(vals.size() - 1);
  const size_t lo = size_t(std::floor(pos)), hi = size_t(std::ceil(pos));
  std::nth_element(vals.begin(), vals.begin() + lo, vals.end());
  const double vlo = vals[lo];
  const double vhi = hi == lo ? vlo : *std::min_element(vals.begin() + lo + 1, vals.end());
  const double q = vlo + (pos - double(lo)) * (vhi - vlo);
  std::vector<double> out(h_raw.size(), 0.0);
  for (int p : hand_pixels_) out[p] = std::max(h_raw[p] - q, 0.0);
  return out;
}

std::vector<double> PressureRenderer::disk_means(const std::vector<double>& h) const {
  EGOPD_CHECK(h.size() == size_t(size_) * size_, "heatmap size");
  std::vector<double> p(num_sensors(), 0.0);
  for (int m = 0; m < num_sensors(); ++m) {
    if (disks_[m].empty()) continue;
    double s = 0;
    for (int v : disks_[m]) s += h[hand_pixels_[v]];
    p[m] = s / double(disks_[m].size());
  }
  return p;
}

std::vector<double> PressureRenderer::readout(const std::vector<double>& h_norm) const {
  const std::vector<double> pd = disk_means(h_norm);
  const Eigen::VectorXd p = RgA_ * Eigen::Map<const Eigen::VectorXd>(pd.data(), pd.size());
  std::vector<double> out(p.size());
  for (int m = 0; m < int(p.size()); ++m) out[m] = std::max(0.0, p[m]);
  return out;
}

PressureRenderer::Frame PressureRenderer::process_frame(const float* chw) const {
  Frame f;
  f.h_raw = heatmap_from_image(chw);
  f.h_norm = percentile_floor(f.h_raw);
  const std::vector<double> pd = disk_means(f.h_norm);
  f.h_std = render(pd);
  f.p = ridge_solve(f.h_std);
  for (double& x : f.p) x = std::max(0.0, x);
  return f;
}

std::vector<double> PressureRenderer::prototype_heatmap() const {
  return render(std::vector<double>(num_sensors(), normalize_reading(100.0)));
}

Tensor PressureRenderer::prototype_image() const {
  return heatmap_to_image(prototype_heatmap(), size_).reshaped(Shape{1, 3, size_, size_});
}

Tensor heatmap_to_image(const std::vector<double>& h, int size) {
  const size_t n = size_t(size) * size;
  EGOPD_CHECK(h.size() == n, "heatmap size");
  Tensor t(Shape{3, size, size});
  for (size_t k = 0; k < n; ++k) {
    const float v = float(2.0 * h[k] - 1.0);
    t[k] = t[n + k] = t[2 * n + k] = v;
  }
  return t;
}

}  // namespace egopd
