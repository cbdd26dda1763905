// locateTdoa's problem: residuals, cost and robust-weighted normal equations
// in row space (TDoA rows) or anchor space (the pair graph's pseudo-ranges
// with the common range c), the Levenberg-Marquardt that solves it, and the
// default loss of its rows.
#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>

#include "estimation/init/tdoa_detail.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo::tdoa_detail {

double tdoaResidual(const Row& o, const Vec3& p, double sigma_m) {
  return (o.diff_m - ((p - o.b).norm() - (p - o.a).norm())) / sigma_m;
}

double usResidual(const UsRow& u, const Vec3& p, double sigma_m) {
  return (u.range_m - (p - u.beacon).norm()) / sigma_m;
}

double pseudoResidual(const AnchorObs& o, const Vec4& x) {
  return (o.D_m - (x.head<3>() - o.a).norm() - x(3)) / o.sigma_m;
}

double costOf(const Problem& pr, const Vec4& x) {
  const Vec3 p = x.head<3>();
  double c = 0.0;
  if (pr.anchor_space) {
    for (const AnchorObs& o : pr.pseudo) c += pr.pseudo_loss.rho(pseudoResidual(o, x));
  } else {
    for (std::size_t i = 0; i < pr.rows.size(); ++i) {
      if (pr.row_used[i]) c += pr.loss.rho(tdoaResidual(pr.rows[i], p, pr.sigma_m));
    }
  }
  for (const UsRow& u : pr.us) c += pr.us_loss.rho(usResidual(u, p, pr.us_sigma_m));
  const double rb = pr.params->band.residual(p.z());
  c += 0.5 * rb * rb;
  if (pr.height_prior) {
    const double rh = (p.z() - pr.height_prior_z) / pr.height_prior_sigma;
    c += 0.5 * rh * rh;
  }
  return c;
}

/// Unit vector from `anchor` to p (zero on the anchor).
Vec3 unitFrom(const Vec3& anchor, const Vec3& p) {
  const Vec3 d = p - anchor;
  const double n = d.norm();
  return n > 1e-9 ? Vec3(d / n) : Vec3(Vec3::Zero());
}

/// Robust-weighted Gauss-Newton system at x: H dx = -g. H_data: the position
/// block of the measurements alone (no band, no height prior).
void linearize(const Problem& pr, const Vec4& x, Mat4& H, Vec4& g, Mat3* H_data) {
  H.setZero();
  g.setZero();
  const Vec3 p = x.head<3>();
  if (pr.anchor_space) {
    for (const AnchorObs& o : pr.pseudo) {
      const double r = pseudoResidual(o, x);
      Vec4 J;
      J << -unitFrom(o.a, p) / o.sigma_m, -1.0 / o.sigma_m;
      const double w = pr.pseudo_loss.weight(r);
      H.noalias() += w * J * J.transpose();
      g.noalias() += w * J * r;
    }
  } else {
    for (std::size_t i = 0; i < pr.rows.size(); ++i) {
      if (!pr.row_used[i]) continue;
      const Row& o = pr.rows[i];
      const double r = tdoaResidual(o, p, pr.sigma_m);
      const Vec3 J = -(unitFrom(o.b, p) - unitFrom(o.a, p)) / pr.sigma_m;
      const double w = pr.loss.weight(r);
      H.topLeftCorner<3, 3>().noalias() += w * J * J.transpose();
      g.head<3>().noalias() += w * J * r;
    }
  }
  for (const UsRow& u : pr.us) {
    const double r = usResidual(u, p, pr.us_sigma_m);
    const Vec3 J = -unitFrom(u.beacon, p) / pr.us_sigma_m;
    const double w = pr.us_loss.weight(r);
    H.topLeftCorner<3, 3>().noalias() += w * J * J.transpose();
    g.head<3>().noalias() += w * J * r;
  }
  if (H_data) {
    // Position information with c eliminated (Schur complement).
    *H_data = H.topLeftCorner<3, 3>();
    if (pr.anchor_space && H(3, 3) > 1e-12) *H_data -= H.topRightCorner<3, 1>() * H.bottomLeftCorner<1, 3>() / H(3, 3);
  }
  const double rb = pr.params->band.residual(p.z());
  const double jb = pr.params->band.derivative(p.z());
  H(2, 2) += jb * jb;
  g(2) += jb * rb;
  if (pr.height_prior) {
    const double ih = 1.0 / pr.height_prior_sigma;
    H(2, 2) += ih * ih;
    g(2) += ih * ih * (p.z() - pr.height_prior_z);
  }
  if (!pr.anchor_space) {
    H(3, 3) = 1.0;  // c is not a variable in row space
    g(3) = 0.0;
  }
}

/// Levenberg-Marquardt from x0 at the problem's current ultrasonic sigma.
Solution levenbergMarquardt(const Problem& pr, const Vec4& x0) {
  Solution s;
  s.x = x0;
  if (!pr.anchor_space) s.x(3) = 0.0;
  s.cost = costOf(pr, s.x);
  double lambda = 1e-3;
  Mat4 H;
  Vec4 g;
  for (int it = 0; it < pr.params->max_iterations; ++it) {
    linearize(pr, s.x, H, g);
    bool accepted = false;
    bool converged = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Mat4 A = H;
      A.diagonal() += lambda * (H.diagonal().array() + 1e-9).matrix();
      const Vec4 step = A.ldlt().solve(-g);
      if (!step.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      const Vec4 x1 = s.x + step;
      const double c1 = costOf(pr, x1);
      if (c1 <= s.cost) {
        converged = step.norm() < 1e-10 * (1.0 + s.x.norm()) || s.cost - c1 < 1e-15 * (1.0 + s.cost);
        s.x = x1;
        s.cost = c1;
        lambda = std::max(1e-12, lambda * 0.2);
        accepted = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted || converged) break;
  }
  linearize(pr, s.x, s.H, g, &s.H_data);
  return s;
}

/// Both passes: ultrasonic first at the TDoA sigma (so that a start decimetres
/// off still feels them), then at their own.
Solution refine(Problem& pr, const Vec4& x0, double us_sigma_final) {
  if (pr.us.empty()) {
    pr.us_sigma_m = us_sigma_final;
    return levenbergMarquardt(pr, x0);
  }
  pr.us_sigma_m = std::max(us_sigma_final, pr.sigma_m);
  const Solution first = levenbergMarquardt(pr, x0);
  pr.us_sigma_m = us_sigma_final;
  return levenbergMarquardt(pr, first.x);
}

/// Anchor space: the common range c that best explains the pseudo-ranges at
/// p (tried at every anchor's own value: the clean anchors agree on one).
double bestOffset(const Problem& pr, const Vec3& p) {
  double best_c = 0.0, best_cost = std::numeric_limits<double>::infinity();
  for (const AnchorObs& k : pr.pseudo) {
    const double c = k.D_m - (p - k.a).norm();
    double cost = 0.0;
    for (const AnchorObs& o : pr.pseudo) cost += pr.pseudo_loss.rho((o.D_m - (p - o.a).norm() - c) / o.sigma_m);
    if (cost < best_cost) {
      best_cost = cost;
      best_c = c;
    }
  }
  return best_c;
}

double median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  double m = *mid;
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), mid));
  return m;
}

/// makeRangeLoss("asymmetric") with its default parameters. Its whitened
/// NLOS scale is the IQR heuristic (1.349, whatever sigma is), so one
/// instance serves every sigma; built once because its density table takes
/// tens of milliseconds.
RobustLossPtr defaultAsymmetricLoss() {
  static const RobustLossPtr kLoss = makeRangeLoss("asymmetric", RangeNoiseParams{});
  return kLoss;
}

}  // namespace rilo::tdoa_detail
