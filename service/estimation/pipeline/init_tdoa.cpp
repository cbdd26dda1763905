#include "estimation/pipeline/init_tdoa.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>

#include "estimation/noise/noise_model_factory.h"
#include "estimation/pipeline/init_format.h"
#include "estimation/pipeline/init_range_loss.h"

namespace rilo {

using init_detail::strprintf;

void TdoaFixParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("TdoaFixParams.") + field + " " + rule);
  };
  if (!(sigma_m > 0.0) || !std::isfinite(sigma_m)) fail("sigma_m", "must be finite and > 0");
  if (!(ultrasonic_sigma_m > 0.0) || !std::isfinite(ultrasonic_sigma_m)) {
    fail("ultrasonic_sigma_m", "must be finite and > 0");
  }
  if (!(ultrasonic_offset_m >= 0.0) || !std::isfinite(ultrasonic_offset_m)) {
    fail("ultrasonic_offset_m", "must be finite and >= 0");
  }
  if (!(ultrasonic_short_side_huber_k > 0.0)) fail("ultrasonic_short_side_huber_k", "must be > 0");
  if (max_hypotheses < 1) fail("max_hypotheses", "must be >= 1");
  if (refine_candidates < 1) fail("refine_candidates", "must be >= 1");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (min_anchors < 4) fail("min_anchors", "must be >= 4 (3 independent differences for 3 unknowns)");
  if (min_measurements < 3) fail("min_measurements", "must be >= 3");
  if (!(inlier_sigmas > 0.0)) fail("inlier_sigmas", "must be > 0");
  if (!(max_rms_m > 0.0)) fail("max_rms_m", "must be > 0");
  if (!(max_pdop > 0.0)) fail("max_pdop", "must be > 0");
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) fail("min_inlier_fraction", "must be in [0, 1]");
  if (!(ambiguity_cost_gap >= 0.0)) fail("ambiguity_cost_gap", "must be >= 0");
  band.validate("TdoaFixParams.band");
}

// ---------------------------------------------------------------------------
// Closed forms

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

// ---------------------------------------------------------------------------
// The fix

namespace {

struct Row {
  Vec3 a;             ///< reference anchor (m)
  Vec3 b;             ///< other anchor (m)
  double diff_m;      ///< |p - b| - |p - a| measured (m)
  std::uint32_t id_a;
  std::uint32_t id_b;
};

struct UsRow {
  Vec3 beacon;        ///< ultrasonic beacon (m)
  double range_m;
  std::uint32_t id;
};

/// Loss of the whitened TDoA residual; asymmetric losses mirrored (either
/// anchor of a row can be the blocked one).
struct TdoaLoss {
  RobustLossPtr loss;
  bool mirror = false;
  double rho(double r) const { return loss->loss(mirror ? std::abs(r) : r); }
  double weight(double r) const { return loss->weight(mirror ? std::abs(r) : r); }
};

/// Pseudo-range of an anchor of the pair graph (anchor space):
///   D_k = |p - A_k| + c + e_k,
/// c the unknown common range (the receiver clock of GNSS), e_k >= 0 anchor
/// k's NLOS excess over the window.
struct AnchorObs {
  Vec3 a;             ///< anchor (m)
  double D_m;         ///< D_k - D_root from the pair graph (m)
  double sigma_m;     ///< its std-dev (m)
  std::uint32_t id;
};

using Vec4 = Eigen::Vector4d;
using Mat4 = Eigen::Matrix4d;

/// State x = (p, c): tag position (m) and the common range c (m; anchor space
/// only, held fixed in row space).
struct Problem {
  std::vector<Row> rows;
  std::vector<char> row_used;      ///< row space: the row is in the cost (touches no rejected anchor)
  std::vector<AnchorObs> pseudo;   ///< anchor space observations
  bool anchor_space = false;       ///< cost over `pseudo` with (p, c), else over `rows` with p
  std::vector<UsRow> us;
  TdoaLoss loss;                   ///< of the rows
  InitRangeLoss pseudo_loss;       ///< of the pseudo-ranges: NLOS tail on the long side
  InitRangeLoss us_loss;
  double sigma_m = 1.0;
  double us_sigma_m = 1.0;   ///< ultrasonic sigma of the current pass (m)
  const TdoaFixParams* params = nullptr;
  /// Gaussian height prior (the band as N(mid, width^2 / 12)) when the
  /// geometry leaves the height to the band.
  bool height_prior = false;
  double height_prior_z = 0.0;
  double height_prior_sigma = 1.0;
};

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
void linearize(const Problem& pr, const Vec4& x, Mat4& H, Vec4& g, Mat3* H_data = nullptr) {
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

struct Solution {
  Vec4 x = Vec4::Zero();
  double cost = std::numeric_limits<double>::infinity();
  Mat4 H = Mat4::Zero();       ///< robust-weighted normal matrix at x (whitened)
  Mat3 H_data = Mat3::Zero();  ///< position information of the measurements alone
  Vec3 p() const { return x.head<3>(); }
};

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

/// D_k - D_root of the largest connected component of the pair graph.
struct PairGraph {
  std::vector<std::uint32_t> anchors;  ///< component anchor ids; anchors[0] is the root
  std::vector<double> D;               ///< D_k - D_root (m), same order
  std::vector<double> sd;              ///< std-dev of D_k in row sigmas, without the common offset
  int anchors_total = 0;               ///< distinct anchors over all rows
  int components = 0;
};

PairGraph buildPairGraph(const std::vector<Row>& rows) {
  PairGraph out;
  std::map<std::uint32_t, int> index;
  for (const Row& o : rows) {
    index.emplace(o.id_a, 0);
    index.emplace(o.id_b, 0);
  }
  std::vector<std::uint32_t> ids;
  for (auto& [id, k] : index) {
    k = static_cast<int>(ids.size());
    ids.push_back(id);
  }
  const int n = static_cast<int>(ids.size());
  out.anchors_total = n;
  if (n == 0) return out;

  // Per unordered pair (lo < hi): values of D_hi - D_lo.
  std::map<std::pair<int, int>, std::vector<double>> pairs;
  std::vector<int> rows_of(static_cast<std::size_t>(n), 0);
  std::vector<int> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int k) {
    while (parent[static_cast<std::size_t>(k)] != k) {
      parent[static_cast<std::size_t>(k)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(k)])];
      k = parent[static_cast<std::size_t>(k)];
    }
    return k;
  };
  for (const Row& o : rows) {
    const int ka = index.at(o.id_a), kb = index.at(o.id_b);
    if (ka < kb) {
      pairs[{ka, kb}].push_back(o.diff_m);
    } else {
      pairs[{kb, ka}].push_back(-o.diff_m);
    }
    ++rows_of[static_cast<std::size_t>(ka)];
    ++rows_of[static_cast<std::size_t>(kb)];
    parent[static_cast<std::size_t>(find(ka))] = find(kb);
  }
  // Largest component (anchors, then rows).
  std::map<int, std::pair<int, int>> comp;  // root -> (anchors, rows)
  for (int k = 0; k < n; ++k) {
    auto& c = comp[find(k)];
    ++c.first;
    c.second += rows_of[static_cast<std::size_t>(k)];
  }
  out.components = static_cast<int>(comp.size());
  int best_root = comp.begin()->first;
  for (const auto& [root, c] : comp) {
    if (c > comp[best_root]) best_root = root;
  }
  std::vector<int> members;
  for (int k = 0; k < n; ++k) {
    if (find(k) == best_root) members.push_back(k);
  }
  // Reference: the member with most rows.
  std::stable_sort(members.begin(), members.end(), [&](int x, int y) {
    return rows_of[static_cast<std::size_t>(x)] > rows_of[static_cast<std::size_t>(y)];
  });
  const int m = static_cast<int>(members.size());
  std::vector<int> local(static_cast<std::size_t>(n), -1);
  for (int i = 0; i < m; ++i) local[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])] = i;

  // Weighted least squares over the pair medians, D_root = 0 (Laplacian
  // system), weights = 1 / variance of the median in row variances (the mean
  // of 1-2 rows; pi / (2 n) for n >= 3).
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(m, m);
  VecX rhs = VecX::Zero(m);
  for (auto& [pair, values] : pairs) {
    const int i = local[static_cast<std::size_t>(pair.first)], j = local[static_cast<std::size_t>(pair.second)];
    if (i < 0 || j < 0) continue;
    const auto n_rows = static_cast<double>(values.size());
    const double w = values.size() <= 2 ? n_rows : 2.0 * n_rows / M_PI;
    const double v = median(values);
    L(i, i) += w;
    L(j, j) += w;
    L(i, j) -= w;
    L(j, i) -= w;
    rhs(j) += w * v;
    rhs(i) -= w * v;
  }
  VecX D = VecX::Zero(m);
  if (m > 1) D.tail(m - 1) = L.bottomRightCorner(m - 1, m - 1).ldlt().solve(rhs.tail(m - 1));
  // Covariance of D up to the common offset: the pseudo-inverse of L (its
  // gauge is the one of least variance, sum D = 0).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(L);
  VecX var = VecX::Zero(m);
  const double lambda_max = eig.eigenvalues().maxCoeff();
  for (int k = 0; k < m; ++k) {
    const double lambda = eig.eigenvalues()(k);
    if (lambda > 1e-9 * lambda_max) var += eig.eigenvectors().col(k).cwiseAbs2() / lambda;
  }
  for (int i = 0; i < m; ++i) {
    out.anchors.push_back(ids[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])]);
    out.D.push_back(D(i));
    out.sd.push_back(std::sqrt(std::max(var(i), 1e-6)));
  }
  return out;
}

/// Ultrasonic trilateration (seed eq. 8, sphere subtraction): 2 V_j^T x =
/// rho_0^2 + |V_j|^2 - rho_j^2 with x = p - U_0. Coplanar beacons (the
/// ceiling): in-plane part by least squares, out-of-plane +-t.
int rangeIntersection(const std::vector<Vec3>& beacons, const std::vector<double>& ranges, std::array<Vec3, 2>& out) {
  const auto n = static_cast<Eigen::Index>(beacons.size());
  if (n < 3) return 0;
  MatX3 V(n - 1, 3);
  VecX c(n - 1);
  for (Eigen::Index j = 1; j < n; ++j) {
    const Vec3 v = beacons[static_cast<std::size_t>(j)] - beacons[0];
    V.row(j - 1) = 2.0 * v.transpose();
    c(j - 1) = ranges[0] * ranges[0] + v.squaredNorm() -
               ranges[static_cast<std::size_t>(j)] * ranges[static_cast<std::size_t>(j)];
  }
  const Eigen::JacobiSVD<MatX3> svd(V, Eigen::ComputeFullV);
  const Vec3 sv = svd.singularValues();
  if (!(sv(0) > 1e-9) || sv(1) <= 1e-6 * sv(0)) return 0;
  if (sv(2) > 1e-2 * sv(0)) {
    out[0] = beacons[0] + Vec3(V.colPivHouseholderQr().solve(c));
    return out[0].allFinite() ? 1 : 0;
  }
  const Eigen::Matrix<double, 3, 2> E = svd.matrixV().leftCols<2>();
  const Vec3 normal = svd.matrixV().col(2);
  const Eigen::Vector2d u = (V * E).colPivHouseholderQr().solve(c);
  const Vec3 x_plane = E * u;
  double t2 = 0.0;
  for (Eigen::Index j = 0; j < n; ++j) {
    const Vec3 v = beacons[static_cast<std::size_t>(j)] - beacons[0];
    const double rj = ranges[static_cast<std::size_t>(j)];
    t2 += rj * rj - (x_plane - v).squaredNorm();
  }
  const double t = std::sqrt(std::max(0.0, t2 / static_cast<double>(n)));
  out[0] = beacons[0] + x_plane + t * normal;
  out[1] = beacons[0] + x_plane - t * normal;
  return out[0].allFinite() ? 2 : 0;
}

/// Best-fit plane (centroid, unit normal with n.z >= 0) of points; false for < 3.
bool bestFitPlane(const std::vector<Vec3>& pts, Vec3& centroid, Vec3& normal) {
  if (pts.size() < 3) return false;
  centroid = Vec3::Zero();
  for (const Vec3& p : pts) centroid += p;
  centroid /= static_cast<double>(pts.size());
  MatX3 centered(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i)
    centered.row(static_cast<Eigen::Index>(i)) = (pts[i] - centroid).transpose();
  const Eigen::JacobiSVD<MatX3> svd(centered, Eigen::ComputeFullV);
  normal = svd.matrixV().col(2);
  if (normal.z() < 0.0) normal = -normal;
  return true;
}

double binomial(int n, int k) {
  double c = 1.0;
  for (int i = 1; i <= k; ++i) c = c * static_cast<double>(n - k + i) / static_cast<double>(i);
  return c;
}

/// 4-anchor subsets of {0..m-1}: all of them (lexicographic) up to `max`,
/// else `max` random ones from a fixed seed (deterministic fixes).
std::vector<std::array<int, 4>> anchorSubsets(int m, int max) {
  std::vector<std::array<int, 4>> out;
  if (m < 5) return out;  // with 4 anchors the all-anchor closed form is the only subset
  if (binomial(m, 4) <= static_cast<double>(max)) {
    for (int a = 0; a < m; ++a)
      for (int b = a + 1; b < m; ++b)
        for (int c = b + 1; c < m; ++c)
          for (int d = c + 1; d < m; ++d) out.push_back({a, b, c, d});
    return out;
  }
  std::mt19937 rng(0x7d0a5eedU);
  std::vector<int> idx(static_cast<std::size_t>(m));
  std::iota(idx.begin(), idx.end(), 0);
  std::set<std::array<int, 4>> seen;
  for (int tries = 0; static_cast<int>(out.size()) < max && tries < 20 * max; ++tries) {
    for (int i = 0; i < 4; ++i) {
      std::uniform_int_distribution<int> pick(i, m - 1);
      std::swap(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(pick(rng))]);
    }
    std::array<int, 4> s{idx[0], idx[1], idx[2], idx[3]};
    std::sort(s.begin(), s.end());
    if (seen.insert(s).second) out.push_back(s);
  }
  return out;
}

/// makeRangeLoss("asymmetric") with its default parameters. Its whitened
/// NLOS scale is the IQR heuristic (1.349, whatever sigma is), so one
/// instance serves every sigma; built once because its density table takes
/// tens of milliseconds.
RobustLossPtr defaultAsymmetricLoss() {
  static const RobustLossPtr kLoss = makeRangeLoss("asymmetric", RangeNoiseParams{});
  return kLoss;
}

[[noreturn]] void badInput(const std::string& what) { throw std::invalid_argument("locateTdoa: " + what); }

}  // namespace

TdoaFix locateTdoa(std::span<const TdoaSample> tdoa, std::span<const UltrasonicSample> ultrasonic, std::int64_t t_ns,
                   const std::vector<Vec3>& p_w_anchors, const TdoaFixParams& params) {
  params.validate();
  const std::size_t n_anchors = p_w_anchors.size();
  auto anchorAt = [&](std::uint32_t id, const std::string& field) -> const Vec3& {
    if (id >= n_anchors) {
      badInput(field + " = " + std::to_string(id) + ": unknown anchor id (" + std::to_string(n_anchors) +
               " anchors)");
    }
    if (!p_w_anchors[id].allFinite()) {
      badInput("p_w_anchors[" + std::to_string(id) + "] (" + field + ") is not finite");
    }
    return p_w_anchors[id];
  };

  Problem pr;
  pr.params = &params;
  pr.sigma_m = params.sigma_m;
  pr.loss.loss = params.loss ? params.loss : defaultAsymmetricLoss();
  pr.loss.mirror = !pr.loss.loss->isSymmetric();
  const double us_sigma = std::sqrt(params.ultrasonic_sigma_m * params.ultrasonic_sigma_m +
                                    params.ultrasonic_offset_m * params.ultrasonic_offset_m / 3.0);
  pr.us_loss.long_side =
      params.ultrasonic_long_side_loss ? params.ultrasonic_long_side_loss : defaultAsymmetricLoss();
  pr.us_loss.short_side_k = params.ultrasonic_short_side_huber_k;
  pr.us_sigma_m = us_sigma;

  for (std::size_t i = 0; i < tdoa.size(); ++i) {
    const TdoaSample& s = tdoa[i];
    const std::string at = "tdoa[" + std::to_string(i) + "]";
    if (s.anchor_a == s.anchor_b) badInput(at + ": anchor_a == anchor_b (" + std::to_string(s.anchor_a) + ")");
    const Vec3& a = anchorAt(s.anchor_a, at + ".anchor_a");
    const Vec3& b = anchorAt(s.anchor_b, at + ".anchor_b");
    if (!std::isfinite(s.diff_m)) badInput(at + ".diff_m is not finite");
    if ((a - b).norm() < 1e-9) badInput(at + ": anchor_a and anchor_b are at the same position");
    pr.rows.push_back({a, b, s.diff_m, s.anchor_a, s.anchor_b});
  }
  std::map<std::uint32_t, std::vector<double>> us_by_beacon;
  for (std::size_t j = 0; j < ultrasonic.size(); ++j) {
    const UltrasonicSample& u = ultrasonic[j];
    const std::string at = "ultrasonic[" + std::to_string(j) + "]";
    const Vec3& bpos = anchorAt(u.anchor_id, at + ".anchor_id");
    if (!std::isfinite(u.range_m)) badInput(at + ".range_m is not finite");
    if (u.range_m < 0.0) badInput(at + ".range_m is negative");
    pr.us.push_back({bpos, u.range_m, u.anchor_id});
    us_by_beacon[u.anchor_id].push_back(u.range_m);
  }

  TdoaFix fix;
  fix.t_ns = t_ns;
  fix.measurements = static_cast<int>(pr.rows.size());
  fix.ultrasonic_ranges = static_cast<int>(pr.us.size());
  fix.beacons_heard = static_cast<int>(us_by_beacon.size());
  const PairGraph graph = buildPairGraph(pr.rows);
  fix.anchors_heard = graph.anchors_total;

  // Enough information? Each connected group of anchors gives (size - 1)
  // independent differences; each beacon one range.
  const int needed = params.min_anchors - 1;
  const int independent = graph.anchors_total - graph.components;
  if (independent + fix.beacons_heard < needed) {
    fix.failure = TdoaFixFailure::kTooFewAnchors;
    fix.message = strprintf("%d anchors heard (%d independent differences) and %d ultrasonic beacons, need %d anchors",
                            fix.anchors_heard, independent, fix.beacons_heard, params.min_anchors);
    if (fix.beacons_heard == 0) fix.message += " (each ultrasonic beacon stands in for one)";
    return fix;
  }
  if (fix.measurements + fix.ultrasonic_ranges < params.min_measurements) {
    fix.failure = TdoaFixFailure::kTooFewAnchors;
    fix.message = strprintf("%d measurements in the window, need %d", fix.measurements + fix.ultrasonic_ranges,
                            params.min_measurements);
    return fix;
  }

  // Hypotheses.
  std::vector<Vec3> candidates;
  std::string closed_form_failure;
  auto addClosedForm = [&](const std::vector<int>& members) {
    const std::uint32_t ref = graph.anchors[static_cast<std::size_t>(members[0])];
    std::vector<Vec3> others;
    std::vector<double> d;
    for (std::size_t i = 1; i < members.size(); ++i) {
      const auto k = static_cast<std::size_t>(members[i]);
      others.push_back(p_w_anchors[graph.anchors[k]]);
      d.push_back(graph.D[k] - graph.D[static_cast<std::size_t>(members[0])]);
    }
    const TdoaClosedForm cf = tdoaSphericalIntersection(p_w_anchors[ref], others, d, 0.02);
    for (int c = 0; c < cf.count; ++c) candidates.push_back(cf.p_w[static_cast<std::size_t>(c)]);
    return cf;
  };
  const int m = static_cast<int>(graph.anchors.size());
  if (m >= 4) {
    std::vector<int> all(static_cast<std::size_t>(m));
    std::iota(all.begin(), all.end(), 0);
    const TdoaClosedForm cf = addClosedForm(all);
    if (cf.degenerate) closed_form_failure = cf.failure;
    if (params.consensus) {
      for (const auto& s : anchorSubsets(m, params.max_hypotheses)) addClosedForm({s[0], s[1], s[2], s[3]});
    }
  }
  if (us_by_beacon.size() >= 3) {
    std::vector<Vec3> beacons;
    std::vector<double> ranges;
    for (const auto& [id, r] : us_by_beacon) {
      beacons.push_back(p_w_anchors[id]);
      ranges.push_back(median(r));
    }
    std::array<Vec3, 2> p{};
    const int k = rangeIntersection(beacons, ranges, p);
    for (int i = 0; i < k; ++i) candidates.push_back(p[static_cast<std::size_t>(i)]);
  }
  if (candidates.empty() && !closed_form_failure.empty()) {
    // The anchors cannot determine the position, whatever the data.
    fix.failure = TdoaFixFailure::kDegenerateGeometry;
    fix.message = "no closed-form solution: " + closed_form_failure;
    return fix;
  }
  // No closed form for a mix of fewer than 4 connected anchors and beacons
  // (nor when noise leaves the closed form without an admissible root):
  // start on each beacon's sphere straight below it (beacons hang from the
  // ceiling) and from the centroid below.
  for (const auto& [id, r] : us_by_beacon) candidates.push_back(p_w_anchors[id] - Vec3(0.0, 0.0, median(r)));
  fix.hypotheses = static_cast<int>(candidates.size());

  // Generic starts: the centroid of all sources at the band's middle height
  // (1 m below the centroid without a band) and its mirror.
  std::vector<Vec3> sources;
  for (std::uint32_t id : graph.anchors) sources.push_back(p_w_anchors[id]);
  for (const auto& [id, r] : us_by_beacon) sources.push_back(p_w_anchors[id]);
  Vec3 centroid = Vec3::Zero(), normal = Vec3::UnitZ();
  const bool have_plane = bestFitPlane(sources, centroid, normal);
  if (!have_plane) {
    for (const Vec3& s : sources) centroid += s;
    if (!sources.empty()) centroid /= static_cast<double>(sources.size());
  }
  auto mirror = [&](const Vec3& p) -> Vec3 { return p - 2.0 * (p - centroid).dot(normal) * normal; };
  Vec3 start = centroid;
  start.z() = params.band.enabled ? params.band.midZ() : centroid.z() - 1.0;
  candidates.push_back(start);
  if (have_plane) candidates.push_back(mirror(start));

  // Consensus in anchor space when >= 4 anchors are connected (header, step 3).
  pr.row_used.assign(pr.rows.size(), 1);
  pr.anchor_space = m >= 4;
  if (pr.anchor_space) {
    for (std::size_t k = 0; k < graph.anchors.size(); ++k) {
      pr.pseudo.push_back({p_w_anchors[graph.anchors[k]], graph.D[k], params.sigma_m * graph.sd[k], graph.anchors[k]});
    }
    pr.pseudo_loss.long_side = pr.loss.loss;
    pr.pseudo_loss.short_side_k = 3.0;
  }
  auto stateAt = [&](const Vec3& p) -> Vec4 {
    Vec4 x;
    x << p, pr.anchor_space ? bestOffset(pr, p) : 0.0;
    return x;
  };

  // Score at the first pass's ultrasonic sigma, refine the best distinct ones.
  pr.us_sigma_m = std::max(us_sigma, params.sigma_m);
  std::vector<std::pair<double, Vec4>> scored;
  for (const Vec3& c : candidates) {
    if (!c.allFinite()) continue;
    const Vec4 x = stateAt(c);
    scored.emplace_back(costOf(pr, x), x);
  }
  std::stable_sort(scored.begin(), scored.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  std::vector<Vec4> starts;
  for (const auto& [c, x] : scored) {
    if (static_cast<int>(starts.size()) >= params.refine_candidates) break;
    const bool distinct = std::none_of(starts.begin(), starts.end(), [&](const Vec4& q) {
      return (q.head<3>() - x.head<3>()).norm() < 0.5;
    });
    if (distinct) starts.push_back(x);
  }
  std::vector<Solution> sols;
  for (const Vec4& x0 : starts) sols.push_back(refine(pr, x0, us_sigma));
  std::size_t best = 0;
  for (std::size_t i = 1; i < sols.size(); ++i) {
    if (sols[i].cost < sols[best].cost) best = i;
  }
  if (have_plane) {
    sols.push_back(refine(pr, stateAt(mirror(sols[best].p())), us_sigma));
    if (sols.back().cost < sols[best].cost) best = sols.size() - 1;
  }
  Solution s = sols[best];
  for (std::size_t i = 0; i < sols.size(); ++i) {
    if (i == best || (sols[i].p() - s.p()).norm() < 0.5) continue;
    fix.second_cost_gap = std::min(fix.second_cost_gap, sols[i].cost - s.cost);
  }
  // Anchors whose pseudo-range disagrees are NLOS for this window: their rows
  // are set aside; the raw rows of the others refine the position (optimal
  // weighting, sporadic outliers by the robust loss).
  // The gate's sigma is at least one path's noise (sigma_m / sqrt(2)): the
  // pair medians carry biases of that order when single rows are NLOS.
  std::set<std::uint32_t> rejected;
  if (pr.anchor_space) {
    for (const AnchorObs& o : pr.pseudo) {
      const double gate = params.inlier_sigmas * std::max(o.sigma_m, params.sigma_m / std::sqrt(2.0));
      const double e = o.D_m - (s.p() - o.a).norm() - s.x(3);
      if (params.consensus && !(std::abs(e) <= gate)) rejected.insert(o.id);
    }
    for (std::size_t i = 0; i < pr.rows.size(); ++i) {
      pr.row_used[i] = !rejected.contains(pr.rows[i].id_a) && !rejected.contains(pr.rows[i].id_b);
    }
    pr.anchor_space = false;
    s = refine(pr, s.x, us_sigma);
  }
  fix.anchors_rejected = static_cast<int>(rejected.size());
  // Height from the band when the measurements know less about it (header).
  if (params.band.enabled) {
    const double sigma_band = (params.band.maxZ() - params.band.minZ()) / std::sqrt(12.0);
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(s.H_data);
    double sigma_z_data = std::numeric_limits<double>::infinity();
    if (eig.eigenvalues().minCoeff() > 1e-12 * std::max(1.0, eig.eigenvalues().maxCoeff())) {
      const Mat3 cov =
          eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
      sigma_z_data = std::sqrt(std::max(0.0, cov(2, 2)));
    }
    if (!(sigma_z_data <= sigma_band)) {
      pr.height_prior = true;
      pr.height_prior_z = params.band.midZ();
      pr.height_prior_sigma = sigma_band;
      Vec4 x0 = s.x;
      x0(2) = std::clamp(x0(2), params.band.minZ(), params.band.maxZ());
      s = refine(pr, x0, us_sigma);
      fix.height_from_band = true;
    }
  }
  pr.us_sigma_m = us_sigma;
  fix.p_w_tag = s.p();
  fix.cost = s.cost;
  fix.mirror_ambiguous = fix.second_cost_gap < params.ambiguity_cost_gap;

  // Quality: inliers, used anchors, RMS.
  std::set<std::uint32_t> used, used_beacons;
  double sum2 = 0.0;
  int rows_considered = 0, inliers_considered = 0;
  for (std::size_t i = 0; i < pr.rows.size(); ++i) {
    const Row& o = pr.rows[i];
    const double r = tdoaResidual(o, fix.p_w_tag, pr.sigma_m);
    rows_considered += pr.row_used[i] ? 1 : 0;
    if (!(std::abs(r) <= params.inlier_sigmas)) continue;
    inliers_considered += pr.row_used[i] ? 1 : 0;
    ++fix.inliers;
    sum2 += r * r;
    used.insert(o.id_a);
    used.insert(o.id_b);
  }
  if (fix.inliers > 0) fix.rms_m = params.sigma_m * std::sqrt(sum2 / fix.inliers);
  fix.anchors_used = static_cast<int>(used.size());
  double us_sum2 = 0.0;
  for (const UsRow& u : pr.us) {
    const double r = usResidual(u, fix.p_w_tag, us_sigma);
    if (!(std::abs(r) <= params.inlier_sigmas)) continue;
    ++fix.ultrasonic_inliers;
    us_sum2 += r * r;
    used_beacons.insert(u.id);
  }
  if (fix.ultrasonic_inliers > 0) fix.ultrasonic_rms_m = us_sigma * std::sqrt(us_sum2 / fix.ultrasonic_inliers);

  // PDOP as in GNSS: rows [u^T 1] for anchors (the unknown common range is
  // the clock), [u^T 0] for beacons.
  Mat4 Q = Mat4::Zero();
  for (std::uint32_t id : used) {
    Vec4 row;
    row << unitFrom(p_w_anchors[id], fix.p_w_tag), 1.0;
    Q.noalias() += row * row.transpose();
  }
  for (std::uint32_t id : used_beacons) {
    Vec4 row;
    row << unitFrom(p_w_anchors[id], fix.p_w_tag), 0.0;
    Q.noalias() += row * row.transpose();
  }
  if (used.empty()) Q(3, 3) = 1.0;  // no TDoA: no common range to solve for
  auto pdopOf = [](const Mat4& q, Vec3* weakest) {
    const Eigen::SelfAdjointEigenSolver<Mat4> eig(q);
    if (!(eig.eigenvalues()(0) > 1e-9 * std::max(1.0, eig.eigenvalues()(3)))) {
      if (weakest) *weakest = eig.eigenvectors().col(0).head<3>();
      return std::numeric_limits<double>::infinity();
    }
    const Mat4 cov =
        eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
    return std::sqrt(std::max(0.0, cov.topLeftCorner<3, 3>().trace()));
  };
  Vec3 weakest = Vec3::Zero();
  if (fix.height_from_band) Q(2, 2) += 1.0;  // the band stands in for the height
  fix.pdop = pdopOf(Q, &weakest);
  const Eigen::SelfAdjointEigenSolver<Mat3> eigH(Mat3(s.H.topLeftCorner<3, 3>()));  // row space: c is not coupled
  if (eigH.eigenvalues().minCoeff() > 1e-12) {
    fix.cov_p = eigH.eigenvectors() * eigH.eigenvalues().cwiseInverse().asDiagonal() * eigH.eigenvectors().transpose();
    fix.sigma_p_m = std::sqrt(std::max(0.0, fix.cov_p.trace()));
  }

  const Vec3& p = fix.p_w_tag;
  std::string summary = strprintf("p=(%.2f, %.2f, %.2f) m", p.x(), p.y(), p.z()) +
                        strprintf(", %d/%d inliers, %d anchors, rms %.3f m", fix.inliers, fix.measurements,
                                  fix.anchors_used, fix.rms_m);
  if (fix.ultrasonic_ranges > 0) {
    summary += strprintf(", ultrasonic %d/%d inliers from %d beacons, rms %.3f m", fix.ultrasonic_inliers,
                         fix.ultrasonic_ranges, static_cast<int>(used_beacons.size()), fix.ultrasonic_rms_m);
  }
  if (fix.anchors_rejected > 0) {
    summary += strprintf(", %d NLOS anchor%s set aside", fix.anchors_rejected, fix.anchors_rejected > 1 ? "s" : "");
  }
  summary += strprintf(", pdop %.1f, sigma %.3f m", fix.pdop, fix.sigma_p_m);
  if (fix.height_from_band) summary += ", height mostly from the band";

  const int info_used = std::max(0, fix.anchors_used - 1) + static_cast<int>(used_beacons.size());
  const bool have_rows = fix.measurements > 0;
  // Rows of the anchors set aside are not counted against the fix (their
  // number is judged at the anchor level).
  const double inlier_fraction =
      have_rows ? static_cast<double>(inliers_considered) / static_cast<double>(std::max(1, rows_considered))
                : static_cast<double>(fix.ultrasonic_inliers) / static_cast<double>(std::max(1, fix.ultrasonic_ranges));
  const double anchor_fraction =
      m > 0 ? static_cast<double>(m - fix.anchors_rejected) / static_cast<double>(m) : 1.0;
  const double rms = have_rows ? fix.rms_m : fix.ultrasonic_rms_m;
  auto fail = [&](TdoaFixFailure why, const std::string& text) {
    fix.failure = why;
    fix.message = text;
  };
  if (!std::isfinite(s.cost) || !s.x.allFinite()) {
    fail(TdoaFixFailure::kDiverged, "TDoA refinement diverged");
  } else if (info_used < needed) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: %d anchors and %d beacons with inliers, need %d anchors; ", fix.anchors_used,
                   static_cast<int>(used_beacons.size()), params.min_anchors) + summary);
  } else if (anchor_fraction < params.min_inlier_fraction) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: %d of %d anchors disagree (NLOS?); ", fix.anchors_rejected, m) + summary);
  } else if (inlier_fraction < params.min_inlier_fraction) {
    fail(TdoaFixFailure::kTooFewInliers,
         strprintf("poor fix: only %.0f%% inliers; ", 100.0 * inlier_fraction) + summary);
  } else if (!(rms <= params.max_rms_m)) {
    fail(TdoaFixFailure::kLargeResiduals, "poor fix: residual RMS too large; " + summary);
  } else if (!(fix.pdop <= params.max_pdop)) {
    std::string why = "poor fix: anchor geometry (PDOP)";
    if (std::abs(weakest.z()) > 0.9) why += ", the height is unobservable (tag in the anchors' plane?)";
    fail(TdoaFixFailure::kPoorGeometry, why + "; " + summary);
  } else if (fix.mirror_ambiguous) {
    fail(TdoaFixFailure::kAmbiguous,
         strprintf("ambiguous fix: a second solution costs only %.2f more; ", fix.second_cost_gap) + summary);
  } else if (!params.band.contains(p.z(), 3.0 * params.band.sigma_m)) {
    fail(TdoaFixFailure::kOutsideHeightBand,
         strprintf("poor fix: height %.2f m outside the height band; ", p.z()) + summary);
  } else {
    fix.valid = true;
    fix.message = summary;
  }
  return fix;
}

}  // namespace rilo
