#pragma once
// Heatmap <-> taxel conversion on the S×S canvas (pressure.md §4.2-§7, egopressurediff.md §4-§5).
// Canvas pixel (row i, column j) has centre (x, y) = (j, i); heatmaps are row-major S*S doubles, 0 off the hand.
#include <Eigen/Dense>
#include <string>
#include <vector>

#include "core/tensor.h"
#include "pressure/hand_template.h"

namespace egopd {

// Aspect-preserving fit of the outline's bounding box onto the canvas (§4.2).
struct CanvasFit {
  int margin = 0;      // μ = round(S/32), half away from zero
  double scale = 1;    // s = (S - 1 - 2μ) / max(W_g, H_g)
  double offset_x = 0, offset_y = 0;
  static CanvasFit fit(const std::vector<Point2>& outline, int size);
  Point2 to_canvas(Point2 g) const { return {scale * g.x + offset_x, scale * g.y + offset_y}; }
};

// Even-odd point-in-polygon test with the ray towards +x, exactly as §4.3 words it.
bool inside_polygon(const std::vector<Point2>& poly, double x, double y);

// Render / read-out constants. Values <= 0 mean "the spec default for this S": σ_A = 6·S/256 px,
// disk r = 3·S/256 px, λ = 1e-3·(S/256)² (λ is given at S = 256; it scales like AᵀA, whose entries count
// pixels, so the regularisation strength relative to the data term does not depend on S).
struct RenderParams {
  double sigma_px = 0;
  double disk_radius_px = 0;
  double lambda = 0;
  double eps = 1e-8;              // ε in A's row normalisation
  double floor_percentile = 5.0;  // percentile subtracted within V (§7 step 2)
  RenderParams resolved(int size) const;  // defaults filled in
};

class PressureRenderer {
 public:
  // Builds V, the sensor canvas positions, A (N_V × M) and the ridge solve (AᵀA + λI)⁻¹ (Cholesky, once).
  PressureRenderer(const HandTemplate& t, int size, RenderParams params = {});

  int size() const { return size_; }
  int num_sensors() const { return int(sensor_px_.size()); }
  int num_hand_pixels() const { return int(hand_pixels_.size()); }
  const RenderParams& params() const { return params_; }
  const CanvasFit& fit() const { return fit_; }
  const std::vector<int>& hand_pixels() const { return hand_pixels_; }  // V as i*S + j, row-major
  const std::vector<Point2>& sensor_canvas() const { return sensor_px_; }
  std::vector<Point2> outline_canvas() const;
  const Eigen::MatrixXd& forward_operator() const { return A_; }  // A
  // Rg = (AᵀA + λI)⁻¹Aᵀ (M × N_V), formed on request (a large matrix; ridge_solve/readout do not need it).
  Eigen::MatrixXd ridge_inverse() const;
  // One line per sensor whose centre is not inside V (the spec asks callers to warn).
  const std::vector<std::string>& warnings() const { return warnings_; }

  // §5: H = A·p on V, 0 elsewhere (S*S). p has M normalised values.
  std::vector<double> render(const std::vector<double>& p) const;
  // §6: p̂ = Rg·h with h the heatmap's values on V (no rectification).
  std::vector<double> ridge_solve(const std::vector<double>& heatmap) const;

  // §7 step 1: H_raw = clamp((mean_c Y + 1)/2, 0, 1) from a [3, S, S] float image in [-1, 1].
  std::vector<double> heatmap_from_image(const float* chw) const;
  // §7 step 2: H_norm = max(H_raw - q, 0) on V, 0 elsewhere; q = the floor percentile of H_raw over V.
  std::vector<double> percentile_floor(const std::vector<double>& h_raw) const;
  // §7 step 3: p'_m = mean of the heatmap over V ∩ disk(c_m, r); 0 if that set is empty.
  std::vector<double> disk_means(const std::vector<double>& h_norm) const;
  // §7 steps 3-6: H_norm -> p̂ = max(0, Rg·A·p') (normalised; Newtons are kPressureMax·p̂).
  std::vector<double> readout(const std::vector<double>& h_norm) const;

  struct Frame {
    std::vector<double> h_raw, h_norm, h_std;  // S*S each
    std::vector<double> p;                      // M normalised taxels (rectified)
  };
  // §7 steps 1-6 for one generated frame [3, S, S].
  Frame process_frame(const float* chw) const;

  // egopressurediff §4: 100 N on every taxel -> normalised (0.5) -> A·p; the heatmap (S*S) and its image
  // 2H-1 replicated in 3 channels as a [1, 3, S, S] tensor.
  std::vector<double> prototype_heatmap() const;
  Tensor prototype_image() const;

 private:
  int size_;
  RenderParams params_;
  CanvasFit fit_;
  std::vector<int> hand_pixels_;
  std::vector<int> pixel_to_v_;  // S*S, -1 off the hand
  std::vector<Point2> outline_px_;
  std::vector<Point2> sensor_px_;
  std::vector<std::vector<int>> disks_;  // per sensor: indices into V
  Eigen::MatrixXd A_, K_, RgA_;  // A, (AᵀA + λI)⁻¹, Rg·A
  std::vector<std::string> warnings_;
};

// egopressurediff §5: a heatmap H (S*S, values in [0, 1]) as the 3-channel image 2H-1, [3, S, S].
Tensor heatmap_to_image(const std::vector<double>& h, int size);

}  // namespace egopd
