#pragma once
// Asymmetric LOS/NLOS range loss of the Ranging-IMU Fusion paper (Sec. III-B, eq. 6-7, Fig. 2),
// implemented as a max-mixture (Olson & Agarwal 2013).
//
// Model of the whitened range excess eps = (measured - true range) / sigma_los:
//   LOS  (prior 1 - w): eps ~ N(0, 1), density phi(eps);
//   NLOS (prior w):     eps = n + c, n ~ N(0, 1), c ~ HalfCauchy(gamma) on [0, inf),
//     density g(eps) = int_0^inf 2 / (pi gamma (1 + (c/gamma)^2)) phi(eps - c) dc   (paper eq. 7)
//                    = 2/pi int_0^{pi/2} phi(eps - gamma tan(theta)) d theta         (Component::kConvolved)
//     or, the paper's simpler variant (Fig. 2b), g(eps) = 2 / (pi gamma (1 + (eps/gamma)^2))
//     for eps >= 0 and 0 below                                                      (Component::kHalfCauchy).
// Loss (the more likely component wins; shared constant removed so rho(0) = 0):
//   rho_LOS(eps)  = eps^2 / 2
//   rho_NLOS(eps) = -log(w g(eps) / phi(0)) + log(1 - w)
//   rho(eps)      = min(rho_LOS(eps), rho_NLOS(eps)).
// rho_LOS - rho_NLOS is strictly increasing (its derivative is the posterior
// mean of c >= 0), so the components cross exactly once, at the decision point
// eps_d > 0: rho = eps^2/2 for eps <= eps_d (in particular exactly Gaussian for
// every eps <= 0, since w < 1/2 and g(eps) <= phi(eps) there) and the heavy NLOS
// tail beyond. If the mode eps_m of g lies beyond the crossing (only for w near
// 1/2 with small gamma), rho_NLOS is replaced by rho_NLOS(max(eps, eps_m)) so rho
// stays non-decreasing; the crossing is then found against that clamped branch
// and rho is flat (weight 0) on [eps_d, eps_m]. See docs/noise-models.md.
//
// The convolved density is tabulated at construction (cubic Hermite in
// s = asinh(eps) over eps in [kTableMinEps, kTableMaxEps], values and
// derivatives from adaptive Gauss-Kronrod quadrature) and follows its analytic
// asymptote beyond; loss/derivative/weight never allocate.
#include <string>
#include <vector>

#include "estimation/noise/robust_loss.h"

namespace rilo {

class AsymmetricLoss final : public RobustLoss {
 public:
  enum class Component {
    kConvolved,   ///< Gaussian * half-Cauchy convolution (paper eq. 7, Fig. 2a)
    kHalfCauchy,  ///< plain half-Cauchy density of the excess (paper Fig. 2b)
  };

  static constexpr double kMinGamma = 1e-3;  ///< supported range of the whitened scale
  static constexpr double kMaxGamma = 1e3;
  static constexpr double kTableMinEps = -8.0;  ///< tabulated range of the convolved density
  static constexpr double kTableMaxEps = 1e4;
  static constexpr int kTableNodes = 1537;

  /// gamma: half-Cauchy scale of the NLOS excess in whitened units
  ///   (gamma_m / sigma_los_m), in [kMinGamma, kMaxGamma];
  /// nlos_weight: prior NLOS probability w, in (0, 0.5).
  /// Throws std::invalid_argument naming the parameter otherwise, and for
  /// kHalfCauchy also when 2 w / (pi gamma) >= (1 - w) phi(0) (the NLOS density
  /// would beat the LOS one at 0, leaving no Gaussian core).
  AsymmetricLoss(double gamma, double nlos_weight, Component component = Component::kConvolved);

  double loss(double r) const override;
  double derivative(double r) const override;
  double weight(double r) const override;
  bool isSymmetric() const override { return false; }
  std::string name() const override;

  double gamma() const { return gamma_; }
  double nlosWeight() const { return w_; }
  Component component() const { return component_; }
  /// eps_d > 0: rho(r) = r^2/2 exactly for r <= eps_d, the NLOS branch beyond.
  double decisionPoint() const { return eps_d_; }
  /// Mode of the NLOS density g (0 for kHalfCauchy).
  double nlosMode() const { return eps_m_; }
  /// True if eps_m > eps_d, i.e. the NLOS branch is flattened on [eps_d, eps_m].
  bool nlosBranchClamped() const { return eps_m_ > eps_d_; }

  /// The two components, with the same shift as loss(): losLoss(r) = r^2/2 and
  /// nlosLoss(r) = -log(w g(r) / phi(0)) + log(1 - w) (unclamped; +inf for
  /// kHalfCauchy at r < 0). Below kTableMinEps the convolved one is computed by
  /// quadrature (slow; never needed by loss()).
  double losLoss(double r) const { return 0.5 * r * r; }
  double nlosLoss(double r) const;
  /// NLOS density g(eps) as used by the loss (table / asymptote / analytic).
  double nlosDensity(double eps) const;

  /// -log g(eps) and d/deps of it for every eps, without allocating: below
  /// kTableMinEps it follows the Gaussian tail's form eps^2/2 + a log(-eps) + b,
  /// matched to the table's end (within 0.1 % of the quadrature down to
  /// -2000). For nlos_component_loss.h.
  double nlosNegLogDensity(double eps, double* d_deps) const;

  /// Reference value of the convolved density by adaptive quadrature in theta
  /// (slow, allocates; for construction and tests).
  static double convolvedDensityByQuadrature(double gamma, double eps);

 private:
  /// -log g(eps) and its derivative for the selected component (unclamped).
  double negLogDensity(double eps, double* d_deps) const;
  double tableNegLogDensity(double eps, double* d_deps) const;
  double asymptoteNegLogDensity(double eps, double* d_deps) const;
  double halfCauchyNegLogDensity(double eps, double* d_deps) const;

  double gamma_;
  double w_;
  Component component_;
  double nlos_offset_;  ///< rho_NLOS(eps) = -log g(eps) + nlos_offset_
  double eps_m_ = 0.0;  ///< mode of g
  double eps_d_ = 0.0;  ///< decision point

  // Convolved table: nodes uniform in s = asinh(eps); per node -log g and h * d(-log g)/ds.
  struct Node {
    double value;
    double slope_h;
  };
  std::vector<Node> table_;
  double s_min_ = 0.0;
  double inv_ds_ = 0.0;
  double table_max_eps_ = 0.0;  ///< eps of the last node; the asymptote takes over beyond
  double log_asym_a_ = 0.0;     ///< log(2 gamma / pi)
};

}  // namespace rilo
