#pragma once
// The NLOS component of the asymmetric model (asymmetric_loss.h, Ranging-IMU Fusion paper,
// eq. 7) alone, for a range that the receiver itself flags as NLOS (the
// DW1000/DW3000 RX-level-minus-first-path-power indicator; RangeNoiseParams::
// nlos_power_gap_db). The mixture would treat such a range as LOS whenever
// its excess is small (below the decision point, a Gaussian pull towards
// zero excess); known to be NLOS, its excess eps = n + c (n ~ N(0, 1), c ~
// HalfCauchy(gamma)) has the convolved density g, whose most likely value
// eps_m is > 0. On the office sim (80 % NLOS) that systematic pull put the tag
// 0.4 m low and cost 16-23 % of the mean error (48 % in the hall).
//
// To keep the RobustLoss conventions (rho(0) = 0, rho ~ r^2/2 near 0, weight
// >= 0 with limit 1), the loss is centred on the mode and rescaled by the
// density's curvature kappa there: the range factor takes the range minus
// modeSigmas() * sigma_los and the sigma sigma_los * sigmaScale(), and
//   rho(r) = -log g(eps_m + s r) + log g(eps_m),  s = sigmaScale() = 1 / sqrt(kappa).
// g is unimodal (a unimodal density convolved with a Gaussian), so rho is
// non-decreasing in |r| on each side. Heavy tail on r > 0 (a longer excess
// than the mode), the LOS Gaussian on r < 0 (a range shorter than the mode):
// there g is more curved than at its mode, so the weight rises towards
// sigmaScale()^2 (1.7 for the defaults); the one loss that up-weights, and
// only where the excess would have to be negative. Tabulated like the
// mixture's NLOS branch (noise-models.md), so its core is r^2/2 to ~1e-6,
// not to rounding. Immutable; loss/derivative/weight never allocate.
#include <string>

#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/robust_loss.h"

namespace rilo {

class NlosComponentLoss final : public RobustLoss {
 public:
  /// Largest supported gamma: beyond it the density is so flat at its mode
  /// that the table's cubic pieces no longer give its curvature (the core's
  /// unit scale); realistic NLOS scales are 1-5 LOS sigmas.
  static constexpr double kMaxGamma = 20.0;

  /// gamma: half-Cauchy scale of the NLOS excess in LOS sigmas (gamma_m /
  /// sigma_los_m), in [AsymmetricLoss::kMinGamma, kMaxGamma]; throws
  /// std::invalid_argument otherwise.
  explicit NlosComponentLoss(double gamma);

  double loss(double r) const override;
  double derivative(double r) const override;
  double weight(double r) const override;
  bool isSymmetric() const override { return false; }
  std::string name() const override { return "nlos-component"; }

  double gamma() const { return density_.gamma(); }
  /// eps_m: the most likely NLOS excess, in LOS sigmas.
  double modeSigmas() const { return eps_m_; }
  /// 1 / sqrt(kappa) >= 1: the component is wider at its mode than the LOS Gaussian.
  double sigmaScale() const { return scale_; }

 private:
  AsymmetricLoss density_;  ///< its NLOS density only (the prior weight plays no part)
  double eps_m_ = 0.0;
  double scale_ = 1.0;
  double neg_log_mode_ = 0.0;  ///< -log g(eps_m)
  double slope_at_mode_ = 0.0;
};

}  // namespace rilo
