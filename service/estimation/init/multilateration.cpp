#include "estimation/init/multilateration.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include "estimation/init/format.h"
#include "estimation/init/range_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {

using init_detail::strprintf;

void MultilaterationParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("MultilaterationParams.") + field + " " + rule);
  };
  if (!(sigma_m > 0.0) || !std::isfinite(sigma_m)) fail("sigma_m", "must be finite and > 0");
  if (!(short_side_huber_k > 0.0)) fail("short_side_huber_k", "must be > 0");
  if (!(velocity_prior_sigma_m_s > 0.0)) fail("velocity_prior_sigma_m_s", "must be > 0");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (min_anchors < 3) fail("min_anchors", "must be >= 3");
  if (min_ranges < 3) fail("min_ranges", "must be >= 3");
  if (!(inlier_sigmas > 0.0)) fail("inlier_sigmas", "must be > 0");
  if (!(max_rms_m > 0.0)) fail("max_rms_m", "must be > 0");
  if (!(max_pdop > 0.0)) fail("max_pdop", "must be > 0");
  if (!(min_band_credit_spread_ratio >= 0.0 && min_band_credit_spread_ratio <= 1.0)) {
    fail("min_band_credit_spread_ratio", "must be in [0, 1]");
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0)) fail("min_inlier_fraction", "must be in [0, 1]");
  if (!(ambiguity_cost_gap >= 0.0)) fail("ambiguity_cost_gap", "must be >= 0");
  band.validate("MultilaterationParams.band");
}

namespace {

using Vec6d = Eigen::Matrix<double, 6, 1>;
using Mat6d = Eigen::Matrix<double, 6, 6>;

struct Obs {
  Vec3 a;           ///< anchor (m)
  double range_m;
  double tau_s;     ///< t_j - t_fix
  std::uint32_t anchor_id;
};

struct Problem {
  std::vector<Obs> obs;
  InitRangeLoss loss;
  double sigma_m;
  const MultilaterationParams* params;
};

struct Solution {
  Vec3 p = Vec3::Zero();
  Vec3 v = Vec3::Zero();
  double cost = std::numeric_limits<double>::infinity();
  Mat6d H = Mat6d::Zero();  ///< robust-weighted normal matrix at the solution (whitened)
};

double residualOf(const Obs& o, const Vec3& p, const Vec3& v, double sigma_m) {
  return (o.range_m - (p + v * o.tau_s - o.a).norm()) / sigma_m;
}

double costOf(const Problem& pr, const Vec3& p, const Vec3& v) {
  double c = 0.0;
  for (const Obs& o : pr.obs) c += pr.loss.rho(residualOf(o, p, v, pr.sigma_m));
  const double rb = pr.params->band.residual(p.z());
  c += 0.5 * rb * rb;
  const Vec3 rv = v / pr.params->velocity_prior_sigma_m_s;
  c += 0.5 * rv.squaredNorm();
  return c;
}

/// Robust-weighted Gauss-Newton system at (p, v): H d = -g.
void linearize(const Problem& pr, const Vec3& p, const Vec3& v, Mat6d& H, Vec6d& g) {
  H.setZero();
  g.setZero();
  for (const Obs& o : pr.obs) {
    const Vec3 d = p + v * o.tau_s - o.a;
    const double rho = d.norm();
    if (rho < 1e-9) continue;
    const Vec3 u = d / rho;
    const double r = (o.range_m - rho) / pr.sigma_m;
    Vec6d J;
    J << -u / pr.sigma_m, -u * o.tau_s / pr.sigma_m;
    const double w = pr.loss.weight(r);
    H.noalias() += w * J * J.transpose();
    g.noalias() += w * J * r;
  }
  const double rb = pr.params->band.residual(p.z());
  const double jb = pr.params->band.derivative(p.z());
  H(2, 2) += jb * jb;
  g(2) += jb * rb;
  const double iv = 1.0 / pr.params->velocity_prior_sigma_m_s;
  for (int k = 3; k < 6; ++k) {
    H(k, k) += iv * iv;
    g(k) += iv * iv * v(k - 3);
  }
  if (!pr.params->fit_velocity) {
    H.block<3, 3>(0, 3).setZero();
    H.block<3, 3>(3, 0).setZero();
    H.block<3, 3>(3, 3).setIdentity();
    g.tail<3>().setZero();
  }
}

Solution solve(const Problem& pr, const Vec3& p0, const Vec3& v0) {
  Solution s;
  s.p = p0;
  s.v = pr.params->fit_velocity ? v0 : Vec3::Zero();
  s.cost = costOf(pr, s.p, s.v);
  double lambda = 1e-3;
  Mat6d H;
  Vec6d g;
  for (int it = 0; it < pr.params->max_iterations; ++it) {
    linearize(pr, s.p, s.v, H, g);
    bool accepted = false;
    for (int attempt = 0; attempt < 10 && !accepted; ++attempt) {
      Mat6d A = H;
      A.diagonal() += lambda * (H.diagonal().array() + 1e-9).matrix();
      const Vec6d step = A.ldlt().solve(-g);
      if (!step.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      const Vec3 p1 = s.p + step.head<3>();
      const Vec3 v1 = s.v + step.tail<3>();
      const double c1 = costOf(pr, p1, v1);
      if (c1 <= s.cost) {
        const bool small = step.head<3>().norm() < 1e-4 && step.tail<3>().norm() < 1e-4;
        s.p = p1;
        s.v = v1;
        s.cost = c1;
        lambda = std::max(1e-9, lambda * 0.2);
        accepted = true;
        if (small) it = pr.params->max_iterations;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted) break;
  }
  linearize(pr, s.p, s.v, s.H, g);
  return s;
}

}  // namespace

TagFix multilaterate(std::span<const RangeSample> ranges, std::int64_t t_ns, const std::vector<Vec3>& p_w_anchors,
                     const MultilaterationParams& params) {
  TagFix fix;
  fix.t_ns = t_ns;
  Problem pr;
  pr.sigma_m = params.sigma_m;
  pr.params = &params;
  pr.loss.long_side = params.long_side_loss;
  if (!pr.loss.long_side) {
    RangeNoiseParams np;
    np.sigma_m = params.sigma_m;
    pr.loss.long_side = makeRangeLoss("asymmetric", np);
  }
  pr.loss.short_side_k = params.short_side_huber_k;

  std::set<std::uint32_t> heard;
  for (const RangeSample& r : ranges) {
    if (r.anchor_id >= p_w_anchors.size() || !std::isfinite(r.range_m) || r.range_m < 0.0) continue;
    pr.obs.push_back({p_w_anchors[r.anchor_id], r.range_m, 1e-9 * static_cast<double>(r.t_ns - t_ns), r.anchor_id});
    heard.insert(r.anchor_id);
  }
  fix.ranges = static_cast<int>(pr.obs.size());
  fix.anchors_heard = static_cast<int>(heard.size());
  const int needed = params.band.enabled ? std::min(3, params.min_anchors) : params.min_anchors;
  if (fix.anchors_heard < needed) {
    fix.message = strprintf("%d anchors heard, need %d", fix.anchors_heard, params.min_anchors);
    if (params.band.enabled && params.min_anchors > 3) fix.message += " (3 with the height band)";
    return fix;
  }
  if (fix.ranges < params.min_ranges) {
    fix.message = strprintf("%d ranges in the window, need %d", fix.ranges, params.min_ranges);
    return fix;
  }

  // Anchor geometry of the heard anchors: centroid and best-fit plane.
  Vec3 centroid = Vec3::Zero();
  for (std::uint32_t id : heard) centroid += p_w_anchors[id];
  centroid /= static_cast<double>(heard.size());
  Eigen::Matrix<double, Eigen::Dynamic, 3> centered(static_cast<Eigen::Index>(heard.size()), 3);
  {
    Eigen::Index row = 0;
    for (std::uint32_t id : heard) centered.row(row++) = (p_w_anchors[id] - centroid).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix<double, Eigen::Dynamic, 3>> svd(centered, Eigen::ComputeFullV);
  Vec3 normal = svd.matrixV().col(2);
  if (normal.z() < 0.0) normal = -normal;
  auto mirror = [&](const Vec3& p) -> Vec3 { return p - 2.0 * (p - centroid).dot(normal) * normal; };

  Vec3 start = centroid;
  start.z() = params.band.enabled ? params.band.midZ() : centroid.z() - 1.0;
  std::vector<Solution> sols;
  sols.push_back(solve(pr, start, Vec3::Zero()));
  sols.push_back(solve(pr, mirror(sols.front().p), sols.front().v));
  sols.push_back(solve(pr, mirror(start), Vec3::Zero()));
  std::size_t best = 0;
  for (std::size_t i = 1; i < sols.size(); ++i) {
    if (sols[i].cost < sols[best].cost) best = i;
  }
  const Solution& s = sols[best];
  for (std::size_t i = 0; i < sols.size(); ++i) {
    if (i == best || (sols[i].p - s.p).norm() < 0.5) continue;
    fix.second_cost_gap = std::min(fix.second_cost_gap, sols[i].cost - s.cost);
  }
  fix.p_w_tag = s.p;
  fix.v_w = s.v;
  fix.cost = s.cost;
  fix.mirror_ambiguous = fix.second_cost_gap < params.ambiguity_cost_gap;

  // Quality.
  std::set<std::uint32_t> used;
  double sum2 = 0.0;
  std::vector<Vec3> dir_sum(p_w_anchors.size(), Vec3::Zero());
  for (const Obs& o : pr.obs) {
    const double r = residualOf(o, s.p, s.v, pr.sigma_m);
    if (std::abs(r) > params.inlier_sigmas) continue;
    ++fix.inliers;
    sum2 += r * r;
    used.insert(o.anchor_id);
    const Vec3 d = s.p + s.v * o.tau_s - o.a;
    if (d.norm() > 1e-9) dir_sum[o.anchor_id] += d.normalized();
  }
  fix.anchors_used = static_cast<int>(used.size());
  if (fix.inliers > 0) fix.rms_m = params.sigma_m * std::sqrt(sum2 / fix.inliers);
  Mat3 GtG = Mat3::Zero();
  for (std::uint32_t id : used) {
    if (dir_sum[id].norm() < 1e-9) continue;
    const Vec3 u = dir_sum[id].normalized();
    GtG += u * u.transpose();
  }
  // The inlier anchors' horizontal spread: the band holds height only, so
  // anchors along a line (a corridor) keep the side of the line open, and
  // the mirror tried above (across their best-fit plane, horizontal for
  // anchors at one height) flips the height, not the side. They get no
  // credit: a review found 8 of 54 corridor fixes 2.4-5.8 m off on the wrong
  // side, claiming PDOP 4-5, once they had it.
  double spread_ratio = 0.0;
  if (used.size() >= 2) {
    Eigen::Vector2d mean = Eigen::Vector2d::Zero();
    for (std::uint32_t id : used) mean += p_w_anchors[id].head<2>();
    mean /= static_cast<double>(used.size());
    Eigen::Matrix2d scatter = Eigen::Matrix2d::Zero();
    for (std::uint32_t id : used) {
      const Eigen::Vector2d d = p_w_anchors[id].head<2>() - mean;
      scatter += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> hs(scatter);
    if (hs.eigenvalues()(1) > 0.0) spread_ratio = std::sqrt(std::max(0.0, hs.eigenvalues()(0) / hs.eigenvalues()(1)));
  }
  if (params.band.enabled) {
    if (fix.anchors_used == 3) {
      GtG(2, 2) += 1.0;  // the band stands in for the 4th anchor
    } else if (spread_ratio >= params.min_band_credit_spread_ratio) {
      // With the band the height is known to its spread whatever the anchors
      // say: its information, whitened by the range sigma, joins theirs. Far
      // anchors a metre above a worn tag leave a PDOP over 10 from height
      // alone, and a start refused forever for a direction the band holds
      // (issue 36: real flights, "pdop 12.4, sigma 0.23 m"); a weak
      // horizontal direction (anchors in a line) still fails.
      const double width_m = params.band.maxZ() - params.band.minZ();
      const double band_var = width_m * width_m / 12.0 + params.band.sigma_m * params.band.sigma_m;
      GtG(2, 2) += params.sigma_m * params.sigma_m / band_var;
    }
  }
  const Eigen::SelfAdjointEigenSolver<Mat3> eig(GtG);
  if (eig.eigenvalues().minCoeff() > 1e-9) fix.pdop = std::sqrt(eig.eigenvalues().cwiseInverse().sum());
  const Eigen::SelfAdjointEigenSolver<Mat6d> eigH(s.H);
  if (eigH.eigenvalues().minCoeff() > 1e-12) {
    const Mat6d cov = eigH.eigenvectors() * eigH.eigenvalues().cwiseInverse().asDiagonal() *
                      eigH.eigenvectors().transpose();
    fix.sigma_p_m = std::sqrt(std::max(0.0, cov.topLeftCorner<3, 3>().trace()));
    const double scale = std::isfinite(fix.rms_m) ? std::max(1.0, fix.rms_m / params.sigma_m) : 1.0;
    fix.cov_p_w = cov.topLeftCorner<3, 3>() * (scale * scale);
  }

  const std::string summary =
      strprintf("p=(%.2f, %.2f, %.2f) m", s.p.x(), s.p.y(), s.p.z()) +
      strprintf(", %d/%d inliers, %d anchors, rms %.2f m", fix.inliers, fix.ranges, fix.anchors_used, fix.rms_m) +
      strprintf(", pdop %.1f, sigma %.2f m", fix.pdop, fix.sigma_p_m);
  const double inlier_fraction = static_cast<double>(fix.inliers) / static_cast<double>(std::max(1, fix.ranges));
  if (!std::isfinite(s.cost) || !s.p.allFinite()) {
    fix.message = "multilateration diverged";
  } else if (fix.anchors_used < needed) {
    fix.message = strprintf("poor fix: %d anchors with inlier ranges, need %d; ", fix.anchors_used, needed) + summary;
  } else if (inlier_fraction < params.min_inlier_fraction) {
    fix.message = strprintf("poor fix: only %.0f%% inliers; ", 100.0 * inlier_fraction) + summary;
  } else if (!(fix.rms_m <= params.max_rms_m)) {
    fix.message = "poor fix: residual RMS too large; " + summary;
  } else if (!(fix.pdop <= params.max_pdop)) {
    fix.message = "poor fix: anchor geometry (PDOP); " + summary;
  } else if (fix.mirror_ambiguous) {
    fix.message = strprintf("ambiguous fix: a second solution costs only %.2f more; ", fix.second_cost_gap) + summary;
  } else if (!params.band.contains(s.p.z(), 3.0 * params.band.sigma_m)) {
    fix.message = strprintf("poor fix: height %.2f m outside the height band; ", s.p.z()) + summary;
  } else {
    fix.valid = true;
    fix.message = summary;
  }
  return fix;
}

}  // namespace rilo
