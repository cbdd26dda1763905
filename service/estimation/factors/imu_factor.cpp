#include "estimation/factors/imu_factor.h"

#include <Eigen/Cholesky>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

// Covariance of xi = [theta; p; v; ...] -> covariance of the residual: the
// rotation rows/columns are mapped by Jr(theta) (d r_R = Jr(theta) d theta).
template <int N>
Eigen::Matrix<double, N, N> toResidualChart(Eigen::Matrix<double, N, N> P, const Vec3& theta) {
  const Mat3 Jr = so3::rightJacobian(theta);
  P.template topRows<3>() = Jr * P.template topRows<3>();
  P.template leftCols<3>() = P.template leftCols<3>() * Jr.transpose();
  return 0.5 * (P + P.transpose());
}

// L^-1 for L L^T = P (lower triangular), so that |L^-1 e|^2 = e^T P^-1 e.
template <int N>
Eigen::Matrix<double, N, N> inverseCholeskyFactor(const Eigen::Matrix<double, N, N>& P, const char* who) {
  using MatN = Eigen::Matrix<double, N, N>;
  const Eigen::LLT<MatN> llt(P);
  if (llt.info() != Eigen::Success) {
    throw std::invalid_argument(std::string(who) + ": preintegration covariance is not positive definite");
  }
  const MatN L_inv = llt.matrixL().solve(MatN::Identity());
  if (!L_inv.allFinite()) throw std::invalid_argument(std::string(who) + ": preintegration covariance is singular");
  return L_inv;
}

void requireSamples(const PreintegratedImu& pim, const char* who) {
  if (pim.numSamples() == 0 || !(pim.dt() > 0.0)) {
    throw std::invalid_argument(std::string(who) + ": pim holds no IMU samples");
  }
}

}  // namespace

Vec9 imuPreintegrationError(const PreintegratedImu& pim, const Pose3& T_w_i, const Vec3& v_w_i, const ImuBias& b_i,
                            const Pose3& T_w_j, const Vec3& v_w_j, ImuErrorJacobians* J) {
  const double T = pim.dt();
  const Vec3 g_w = pim.params().gravityWorld();
  const PreintegratedImu::Delta d = pim.biasCorrectedDelta(b_i);
  const Mat3 R_i_t = T_w_i.R.transpose();
  const Mat3 E = d.R.transpose() * R_i_t * T_w_j.R;  // Exp(r_R)
  const Vec3 r_R = so3::log(E);
  const Vec3 s_p = R_i_t * (T_w_j.p - T_w_i.p - v_w_i * T - (0.5 * T * T) * g_w);
  const Vec3 s_v = R_i_t * (v_w_j - v_w_i - T * g_w);
  Vec9 e;
  e << r_R, s_p - d.p_m, s_v - d.v_m_s;
  if (!J) return e;

  // CombinedImuFactor::evaluate whitens only the blocks set below; the ones
  // zeroed here must stay structurally zero.
  const Mat3 I = Mat3::Identity();
  const Mat3 Jr_inv = so3::rightJacobianInverse(r_R);
  // R_i <- R_i Exp(phi): r_R -> Log(Exp(-dR^T phi) E) = r_R - Jr^-1 E^T dR^T phi; R_i^T y -> R_i^T y + [R_i^T y]x phi.
  J->J_pose_i.setZero();
  J->J_pose_i.block<3, 3>(0, 0) = -Jr_inv * (T_w_j.R.transpose() * T_w_i.R);
  J->J_pose_i.block<3, 3>(3, 0) = so3::hat(s_p);
  J->J_pose_i.block<3, 3>(3, 3) = -I;
  J->J_pose_i.block<3, 3>(6, 0) = so3::hat(s_v);

  J->J_vel_i.topRows<3>().setZero();
  J->J_vel_i.middleRows<3>(3) = -T * R_i_t;
  J->J_vel_i.bottomRows<3>() = -R_i_t;

  J->J_pose_j.setZero();
  J->J_pose_j.block<3, 3>(0, 0) = Jr_inv;
  J->J_pose_j.block<3, 3>(3, 3) = R_i_t * T_w_j.R;

  J->J_vel_j.topRows<6>().setZero();
  J->J_vel_j.bottomRows<3>() = R_i_t;

  // b_g moves theta_corr additively: dR_corr -> dR_corr Exp(Jr(theta_corr) J_theta_bg d b_g).
  J->J_bias_i.setZero();
  J->J_bias_i.block<3, 3>(0, 3) = -Jr_inv * E.transpose() * so3::rightJacobian(d.theta_rad) * pim.J_theta_bg();
  J->J_bias_i.block<6, 3>(3, 0) = -pim.J_xi_ba().bottomRows<6>();
  J->J_bias_i.block<6, 3>(3, 3) = -pim.J_xi_bg().bottomRows<6>();
  return e;
}

// ---------------------------------------------------------------- ImuFactor

ImuFactor::ImuFactor(Key pose_i, Key vel_i, Key pose_j, Key vel_j, Key bias_i, const PreintegratedImu& pim)
    : Factor({pose_i, vel_i, pose_j, vel_j, bias_i}), pim_(pim) {
  requireSamples(pim_, "ImuFactor");
  if (!pim_.hasCovariance()) {
    throw std::invalid_argument("ImuFactor: pim was built with CovarianceMode::kCombined (no 9x9 covariance)");
  }
  sqrt_info_ = inverseCholeskyFactor<9>(toResidualChart<9>(pim_.covariance(), pim_.theta()), "ImuFactor");
}

Vec9 ImuFactor::unwhitenedError(const Values& x) const {
  const auto& k = keys();
  return imuPreintegrationError(pim_, x.pose(k[0]), x.vec3(k[1]), x.bias(k[4]), x.pose(k[2]), x.vec3(k[3]), nullptr);
}

void ImuFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const auto& k = keys();
  ImuErrorJacobians J;
  const Vec9 e = imuPreintegrationError(pim_, x.pose(k[0]), x.vec3(k[1]), x.bias(k[4]), x.pose(k[2]), x.vec3(k[3]),
                                        H ? &J : nullptr);
  // L^-1 is lower triangular, but at these sizes plain coefficient-based
  // products (lazyProduct: no GEMM blocking) are the fastest form.
  const Mat9& L_inv = sqrt_info_;
  r = L_inv * e;
  if (!H) return;
  (*H)[0] = L_inv.lazyProduct(J.J_pose_i);
  (*H)[1] = L_inv.lazyProduct(J.J_vel_i);
  (*H)[2] = L_inv.lazyProduct(J.J_pose_j);
  (*H)[3] = L_inv.lazyProduct(J.J_vel_j);
  (*H)[4] = L_inv.lazyProduct(J.J_bias_i);
}

// -------------------------------------------------------- CombinedImuFactor

CombinedImuFactor::CombinedImuFactor(Key pose_i, Key vel_i, Key bias_i, Key pose_j, Key vel_j, Key bias_j,
                                     const PreintegratedImu& pim)
    : Factor({pose_i, vel_i, bias_i, pose_j, vel_j, bias_j}), pim_(pim) {
  requireSamples(pim_, "CombinedImuFactor");
  if (!pim_.hasCombinedCovariance()) {
    throw std::invalid_argument(
        "CombinedImuFactor: pim was built with CovarianceMode::kPreintegration (no combined covariance)");
  }
  phi_ = pim_.params().biasTransition(pim_.dt());
  sqrt_info_ =
      inverseCholeskyFactor<15>(toResidualChart<15>(pim_.combinedCovariance(), pim_.theta()), "CombinedImuFactor");
}

Vec15 CombinedImuFactor::computeError(const Values& x, ImuErrorJacobians* J) const {
  const auto& k = keys();
  const ImuBias& b_i = x.bias(k[2]);
  Vec15 e;
  e.head<9>() = imuPreintegrationError(pim_, x.pose(k[0]), x.vec3(k[1]), b_i, x.pose(k[3]), x.vec3(k[4]), J);
  e.tail<6>() = x.bias(k[5]).vector() - phi_.cwiseProduct(b_i.vector());
  return e;
}

Vec15 CombinedImuFactor::unwhitenedError(const Values& x) const { return computeError(x, nullptr); }

void CombinedImuFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  ImuErrorJacobians J;
  const Vec15 e = computeError(x, H ? &J : nullptr);
  r = sqrt_info_ * e;
  if (!H) return;
  // Whitened blocks L^-1 J over the nonzero 3x3 blocks of the unwhitened
  // Jacobians only (imuPreintegrationError: r_R does not depend on the
  // positions or velocities, r_p not on v_j, r_v not on the positions; the
  // bias rows are -Phi on b_i and I on b_j): half the multiply-adds of the
  // full 15x9 products, and the smoother relinearizes these factors often.
  // lazyProduct: see ImuFactor::evaluate.
  using Block15x3 = Eigen::Matrix<double, 15, 3>;
  const auto L_R = sqrt_info_.middleCols<3>(0);  // columns of the rotation residual
  const auto L_p = sqrt_info_.middleCols<3>(3);  // position
  const auto L_v = sqrt_info_.middleCols<3>(6);  // velocity
  const auto L_b = sqrt_info_.rightCols<6>();    // bias
  // X_i: [phi_i, rho_i]; rho_i enters r_p only.
  const Block15x3 H_phi_i = L_R.lazyProduct(J.J_pose_i.block<3, 3>(0, 0)) +
                            L_p.lazyProduct(J.J_pose_i.block<3, 3>(3, 0)) +
                            L_v.lazyProduct(J.J_pose_i.block<3, 3>(6, 0));
  (*H)[0].resize(15, 6);
  (*H)[0].leftCols<3>() = H_phi_i;
  (*H)[0].rightCols<3>() = L_p.lazyProduct(J.J_pose_i.block<3, 3>(3, 3));
  // V_i: r_p and r_v.
  (*H)[1] = L_p.lazyProduct(J.J_vel_i.middleRows<3>(3)) + L_v.lazyProduct(J.J_vel_i.bottomRows<3>());
  // B_i: b_a enters r_p, r_v; b_g all three; the bias process -Phi.
  (*H)[2].resize(15, 6);
  (*H)[2].leftCols<3>() = L_p.lazyProduct(J.J_bias_i.block<3, 3>(3, 0)) +
                          L_v.lazyProduct(J.J_bias_i.block<3, 3>(6, 0)) -
                          L_b.leftCols<3>() * phi_.head<3>().asDiagonal();
  (*H)[2].rightCols<3>() = L_R.lazyProduct(J.J_bias_i.block<3, 3>(0, 3)) +
                           L_p.lazyProduct(J.J_bias_i.block<3, 3>(3, 3)) +
                           L_v.lazyProduct(J.J_bias_i.block<3, 3>(6, 3)) -
                           L_b.rightCols<3>() * phi_.tail<3>().asDiagonal();
  // X_j: phi_j enters r_R, rho_j r_p.
  (*H)[3].resize(15, 6);
  (*H)[3].leftCols<3>() = L_R.lazyProduct(J.J_pose_j.block<3, 3>(0, 0));
  (*H)[3].rightCols<3>() = L_p.lazyProduct(J.J_pose_j.block<3, 3>(3, 3));
  // V_j: r_v.
  (*H)[4] = L_v.lazyProduct(J.J_vel_j.bottomRows<3>());
  (*H)[5] = L_b;
}

}  // namespace rilo
