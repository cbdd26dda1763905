#include "evaluation/covariance_consistency.h"

#include <Eigen/Cholesky>
#include <cmath>

#include "evaluation/trajectory_metrics.h"

namespace rilo {
namespace {

// 95 % quantiles of the chi-square distribution.
constexpr double kChi2Dof2P95 = 5.991464547107979;
constexpr double kChi2Dof1P95 = 3.841458820694124;

}  // namespace

CovarianceConsistency covarianceConsistency(const std::vector<TimedPositionCovariance>& published,
                                            const std::vector<GroundTruthPose>& truth, std::int64_t max_dt_ns) {
  // associateByTime pairs poses; only their times are read.
  TumTrajectory times;
  times.reserve(published.size());
  for (const TimedPositionCovariance& p : published) times.push_back({p.t_ns, Pose3()});
  const PoseAssociation association = associateByTime(times, truth, max_dt_ns);

  CovarianceConsistency c;
  std::size_t in_h = 0, in_v = 0;
  double nees = 0.0, var_h = 0.0, err_h = 0.0, var_v = 0.0, err_v = 0.0;
  for (const auto& [k, g] : association.pairs) {
    const Mat3& P = published[k].cov_p_w;
    const Vec3 e = published[k].p_w - truth[g].p_w_b;
    const Eigen::LLT<Mat3> llt(P);
    const bool symmetric = (P - P.transpose()).cwiseAbs().maxCoeff() <= 1e-9 * P.cwiseAbs().maxCoeff();
    if (!P.allFinite() || !e.allFinite() || !symmetric || llt.info() != Eigen::Success) {
      ++c.not_positive_definite;
      continue;
    }
    ++c.poses;
    nees += e.dot(llt.solve(e));
    // A principal submatrix of a positive definite matrix is positive definite.
    const Eigen::Matrix2d P_h = P.topLeftCorner<2, 2>();
    const Eigen::Vector2d e_h = e.head<2>();
    if (e_h.dot(P_h.llt().solve(e_h)) <= kChi2Dof2P95) ++in_h;
    if (e.z() * e.z() <= kChi2Dof1P95 * P(2, 2)) ++in_v;
    var_h += 0.5 * (P(0, 0) + P(1, 1));
    err_h += 0.5 * e_h.squaredNorm();
    var_v += P(2, 2);
    err_v += e.z() * e.z();
  }
  if (c.poses == 0) return c;
  const auto n = static_cast<double>(c.poses);
  c.horizontal_in_95 = static_cast<double>(in_h) / n;
  c.vertical_in_95 = static_cast<double>(in_v) / n;
  c.nees_mean = nees / n;
  c.sigma_horizontal_m = std::sqrt(var_h / n);
  c.error_horizontal_m = std::sqrt(err_h / n);
  c.sigma_vertical_m = std::sqrt(var_v / n);
  c.error_vertical_m = std::sqrt(err_v / n);
  return c;
}

}  // namespace rilo
