// The TDoA closed form (IMU-Ultrasonic-UWB paper, Sec. III-B): spherical intersection of the
// range differences to a reference anchor, the starting hypotheses of
// locateTdoa (tdoa.cpp).
#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <utility>

#include "estimation/init/format.h"
#include "estimation/init/tdoa.h"

namespace rilo {

using init_detail::strprintf;

namespace {

using MatX3 = Eigen::Matrix<double, Eigen::Dynamic, 3>;
using MatX4 = Eigen::Matrix<double, Eigen::Dynamic, 4>;
using VecX = Eigen::VectorXd;

/// Real roots of a R^2 + b R + c = 0 (a ~ 0: the linear root; negative
/// discriminant from noise: the vertex, the closest the parabola gets to 0).
int quadraticRoots(double a, double b, double c, std::array<double, 2>& roots) {
  const double scale = std::max({std::abs(a), std::abs(b), std::abs(c), 1e-300});
  if (std::abs(a) < 1e-12 * scale) {
    if (std::abs(b) < 1e-300) return 0;
    roots[0] = -c / b;
    return 1;
  }
  const double disc = b * b - 4.0 * a * c;
  if (disc < 0.0) {
    roots[0] = -b / (2.0 * a);
    return 1;
  }
  // Stable form: no cancellation between -b and sqrt(disc).
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  roots[0] = q / a;
  if (std::abs(q) < 1e-300) {
    roots[1] = roots[0];
    return 1;
  }
  roots[1] = c / q;
  if (roots[1] < roots[0]) std::swap(roots[0], roots[1]);
  return 2;
}

/// One weighted solve of the spherical-intersection rows for all admissible
/// R. Returns (R, x) pairs through the callback; false when rank-deficient.
struct SiRows {
  MatX3 B;          ///< anchor offsets B_i = A_i - A_ref (m)
  VecX d;           ///< d_i (m)
  VecX c;           ///< |B_i|^2 - d_i^2 (m^2)
  Eigen::Matrix3d E_plane;  ///< columns: in-plane basis (0, 1), normal (2)
  bool planar = false;
};

/// Admissible range of the reference: R >= 0, and R + d_i not far below 0
/// (noise may push a true root a little below the bound; extra candidates are
/// harmless, they are scored later).
bool admissible(const SiRows& s, double R) {
  return std::isfinite(R) && R >= -1e-9 && R + s.d.minCoeff() >= -1.0;
}

/// Candidates (R, x) from the rows weighted by w (3-D or planar branch).
std::vector<std::pair<double, Vec3>> siSolve(const SiRows& s, const VecX& w, bool with_unconstrained) {
  std::vector<std::pair<double, Vec3>> out;
  const Eigen::Index n = s.B.rows();
  const VecX cw = w.cwiseProduct(s.c);
  const VecX gw = w.cwiseProduct(2.0 * s.d);
  if (!s.planar) {
    const MatX3 M = w.asDiagonal() * (2.0 * s.B);
    const Eigen::ColPivHouseholderQR<MatX3> qr(M);
    if (qr.rank() < 3) return out;
    const Vec3 x0 = qr.solve(cw);
    const Vec3 x1 = qr.solve(gw);
    std::array<double, 2> roots{};
    const int k = quadraticRoots(x1.squaredNorm() - 1.0, -2.0 * x0.dot(x1), x0.squaredNorm(), roots);
    for (int i = 0; i < k; ++i) {
      if (admissible(s, roots[static_cast<std::size_t>(i)])) {
        const double R = roots[static_cast<std::size_t>(i)];
        out.emplace_back(R, x0 - R * x1);
      }
    }
    if (with_unconstrained && n >= 4) {
      MatX4 M4(n, 4);
      M4.leftCols<3>() = M;
      M4.col(3) = gw;
      const Eigen::ColPivHouseholderQR<MatX4> qr4(M4);
      if (qr4.rank() == 4) {
        const Eigen::Vector4d xr = qr4.solve(cw);
        if (admissible(s, xr(3))) out.emplace_back(xr(3), xr.head<3>());
      }
    }
    return out;
  }
  // Planar: the rows see only u = E^T x (in-plane); solve (u, R) jointly.
  const Eigen::Matrix<double, 3, 2> E = s.E_plane.leftCols<2>();
  const Vec3 normal = s.E_plane.col(2);
  Eigen::Matrix<double, Eigen::Dynamic, 3> M(n, 3);
  M.leftCols<2>() = w.asDiagonal() * (2.0 * s.B * E);
  M.col(2) = gw;
  const Eigen::ColPivHouseholderQR<Eigen::Matrix<double, Eigen::Dynamic, 3>> qr(M);
  if (qr.rank() < 3) return out;
  const Vec3 ur = qr.solve(cw);
  const double R = ur(2);
  if (!admissible(s, R)) return out;
  const Vec3 x_plane = E * ur.head<2>();
  const double t2 = R * R - x_plane.squaredNorm();
  const double t = std::sqrt(std::max(0.0, t2));
  out.emplace_back(R, x_plane + t * normal);
  if (t > 1e-9) out.emplace_back(R, x_plane - t * normal);
  return out;
}

}  // namespace

TdoaClosedForm tdoaSphericalIntersection(const Vec3& p_w_ref, std::span<const Vec3> p_w_anchors,
                                         std::span<const double> d_m, double planar_tol) {
  if (p_w_anchors.size() != d_m.size()) {
    throw std::invalid_argument("tdoaSphericalIntersection: d_m needs one entry per anchor (" +
                                std::to_string(d_m.size()) + " for " + std::to_string(p_w_anchors.size()) + ")");
  }
  if (!(planar_tol >= 0.0 && planar_tol < 1.0)) {
    throw std::invalid_argument("tdoaSphericalIntersection: planar_tol must be in [0, 1)");
  }
  TdoaClosedForm out;
  const auto n = static_cast<Eigen::Index>(p_w_anchors.size());
  if (n < 3) {
    out.failure = strprintf("%d anchors besides the reference, need 3", static_cast<int>(n));
    return out;
  }
  if (!p_w_ref.allFinite()) {
    out.failure = "reference anchor not finite";
    return out;
  }
  SiRows s;
  s.B.resize(n, 3);
  s.d.resize(n);
  s.c.resize(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (!p_w_anchors[k].allFinite() || !std::isfinite(d_m[k])) {
      out.failure = strprintf("anchor %d or its difference is not finite", static_cast<int>(i));
      return out;
    }
    s.B.row(i) = (p_w_anchors[k] - p_w_ref).transpose();
    s.d(i) = d_m[k];
    s.c(i) = s.B.row(i).squaredNorm() - d_m[k] * d_m[k];
  }
  const Eigen::JacobiSVD<MatX3> svd(s.B, Eigen::ComputeFullV);
  const Vec3 sv = svd.singularValues();
  if (!(sv(0) > 1e-9) || sv(1) <= 1e-9 * sv(0)) {
    out.failure = "anchors collinear with the reference: the position cannot be determined";
    out.degenerate = true;
    return out;
  }
  s.planar = sv(2) < planar_tol * sv(0);
  s.E_plane = svd.matrixV();
  out.planar = s.planar;

  // Unweighted candidates, then one Chan-style re-weighting per candidate:
  // row i's equation error is 2 (R + d_i) times the error of d_i.
  const VecX ones = VecX::Ones(n);
  const std::vector<std::pair<double, Vec3>> first = siSolve(s, ones, true);
  if (first.empty()) {
    out.failure = s.planar ? "coplanar anchors: the differences do not determine the in-plane position"
                           : "no admissible root of the spherical intersection";
    return out;
  }
  for (const auto& [R0, x0] : first) {
    if (out.count >= static_cast<int>(out.p_w.size())) break;
    VecX w(n);
    for (Eigen::Index i = 0; i < n; ++i) w(i) = 1.0 / std::max(R0 + s.d(i), 0.1);
    w /= w.maxCoeff();
    Vec3 best = x0;
    double best_gap = std::numeric_limits<double>::infinity();
    for (const auto& [R1, x1] : siSolve(s, w, false)) {
      // The re-weighted root that continues this candidate (planar: same side).
      const double gap = std::abs(R1 - R0) + (x1 - x0).norm();
      if (gap < best_gap) {
        best_gap = gap;
        best = x1;
      }
    }
    out.p_w[static_cast<std::size_t>(out.count++)] = p_w_ref + best;
  }
  return out;
}

}  // namespace rilo
