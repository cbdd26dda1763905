#include "estimation/factors/prior_factors.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <stdexcept>
#include <string>

#include "math/so3.h"

namespace rilo {
namespace {

[[noreturn]] void throwBadNoise(std::string_view what, const std::string& why) {
  throw std::invalid_argument(std::string(what) + ": " + why);
}

// Vector residuals get rho(|r|) in the Factor base: the sign an asymmetric loss
// needs is gone, so refuse such a loss up front instead of failing in error().
void requireSymmetricLoss(const RobustLoss* loss, const char* who) {
  if (loss != nullptr && !loss->isSymmetric()) {
    throw std::invalid_argument(std::string(who) + ": loss '" + loss->name() +
                                "' is asymmetric; a vector residual needs a symmetric loss");
  }
}

// Relative tolerances of the covariance checks.
constexpr double kSymmetryRelTol = 1e-9;
constexpr double kMinRelativePivot = 1e-12;  // pivot^2 / own diagonal entry

}  // namespace

template <int N>
SqrtInformation<N> SqrtInformation<N>::fromCovariance(const Matrix& cov, std::string_view what) {
  if (!cov.allFinite()) throwBadNoise(what, "covariance must be finite");
  const double max_abs = cov.cwiseAbs().maxCoeff();
  if (!(max_abs > 0.0)) throwBadNoise(what, "covariance must be positive definite (it is zero)");
  if ((cov - cov.transpose()).cwiseAbs().maxCoeff() > kSymmetryRelTol * max_abs) {
    throwBadNoise(what, "covariance must be symmetric");
  }
  const Matrix cov_sym = 0.5 * (cov + cov.transpose());
  const Eigen::LLT<Matrix> llt_cov(cov_sym);
  if (llt_cov.info() != Eigen::Success) throwBadNoise(what, "covariance must be positive definite");
  for (int i = 0; i < N; ++i) {
    // Scale-invariant: each pivot against its own diagonal entry, so sigmas of
    // very different units (1e-7 rad beside 1 m) are accepted.
    const double pivot = llt_cov.matrixLLT()(i, i);  // diagonal of the Cholesky factor
    if (!(pivot * pivot > kMinRelativePivot * cov_sym(i, i))) {
      throwBadNoise(what, "covariance must be positive definite (it is singular or nearly so)");
    }
  }
  Matrix information = llt_cov.solve(Matrix::Identity());
  information = 0.5 * (information + information.transpose());
  const Eigen::LLT<Matrix> llt_info(information);
  if (llt_info.info() != Eigen::Success || !information.allFinite()) {
    throwBadNoise(what, "covariance is too ill-conditioned to invert");
  }
  SqrtInformation out;
  out.U = llt_info.matrixU();  // information = L L^T = U^T U
  return out;
}

template <int N>
SqrtInformation<N> SqrtInformation<N>::fromSigmas(const Vector& sigmas, std::string_view what) {
  for (int i = 0; i < N; ++i) {
    if (!(std::isfinite(sigmas(i)) && sigmas(i) > 0.0)) {
      throwBadNoise(what, "sigma " + std::to_string(i) + " must be positive and finite, got " +
                              std::to_string(sigmas(i)));
    }
  }
  SqrtInformation out;
  out.U = sigmas.cwiseInverse().asDiagonal();
  return out;
}

template struct SqrtInformation<1>;
template struct SqrtInformation<3>;
template struct SqrtInformation<6>;

// ---------------------------------------------------------------------------
PriorPose3Factor::PriorPose3Factor(Key key, const Pose3& T_prior, const SqrtInformation<6>& noise,
                                   RobustLossPtr loss)
    : Factor({key}, std::move(loss)), T_prior_(T_prior), sqrt_info_(noise.U) {
  if (!T_prior.R.allFinite() || !T_prior.p.allFinite()) {
    throw std::invalid_argument("PriorPose3Factor: T_prior must be finite");
  }
  requireSymmetricLoss(this->loss(), "PriorPose3Factor");
}

PriorPose3Factor::PriorPose3Factor(Key key, const Pose3& T_prior, const Mat6& covariance, RobustLossPtr loss)
    : PriorPose3Factor(key, T_prior, SqrtInformation<6>::fromCovariance(covariance, "PriorPose3Factor: covariance"),
                       std::move(loss)) {}

PriorPose3Factor::PriorPose3Factor(Key key, const Pose3& T_prior, const Vec6& sigmas, RobustLossPtr loss)
    : PriorPose3Factor(key, T_prior, SqrtInformation<6>::fromSigmas(sigmas, "PriorPose3Factor: sigmas"),
                       std::move(loss)) {}

void PriorPose3Factor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Pose3& T_w_b = x.pose(keys()[0]);
  const Vec6 xi = T_prior_.local(T_w_b);
  r = sqrt_info_ * xi;
  if (H == nullptr) return;
  Mat6 J_xi_T = Mat6::Zero();
  J_xi_T.topLeftCorner<3, 3>() = so3::rightJacobianInverse(xi.head<3>());
  J_xi_T.bottomRightCorner<3, 3>() = T_prior_.R.transpose() * T_w_b.R;
  (*H)[0] = sqrt_info_ * J_xi_T;
}

// ---------------------------------------------------------------------------
PriorVec3Factor::PriorVec3Factor(Key key, const Vec3& prior, const SqrtInformation<3>& noise, RobustLossPtr loss)
    : Factor({key}, std::move(loss)), prior_(prior), sqrt_info_(noise.U) {
  if (!prior.allFinite()) throw std::invalid_argument("PriorVec3Factor: prior must be finite");
  requireSymmetricLoss(this->loss(), "PriorVec3Factor");
}

PriorVec3Factor::PriorVec3Factor(Key key, const Vec3& prior, const Mat3& covariance, RobustLossPtr loss)
    : PriorVec3Factor(key, prior, SqrtInformation<3>::fromCovariance(covariance, "PriorVec3Factor: covariance"),
                      std::move(loss)) {}

PriorVec3Factor::PriorVec3Factor(Key key, const Vec3& prior, const Vec3& sigmas, RobustLossPtr loss)
    : PriorVec3Factor(key, prior, SqrtInformation<3>::fromSigmas(sigmas, "PriorVec3Factor: sigmas"),
                      std::move(loss)) {}

void PriorVec3Factor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  r = sqrt_info_ * (x.vec3(keys()[0]) - prior_);
  if (H != nullptr) (*H)[0] = sqrt_info_;
}

// ---------------------------------------------------------------------------
PriorBiasFactor::PriorBiasFactor(Key key, const ImuBias& prior, const SqrtInformation<6>& noise,
                                 RobustLossPtr loss)
    : Factor({key}, std::move(loss)), prior_(prior), sqrt_info_(noise.U) {
  if (!prior.vector().allFinite()) throw std::invalid_argument("PriorBiasFactor: prior must be finite");
  requireSymmetricLoss(this->loss(), "PriorBiasFactor");
}

PriorBiasFactor::PriorBiasFactor(Key key, const ImuBias& prior, const Mat6& covariance, RobustLossPtr loss)
    : PriorBiasFactor(key, prior, SqrtInformation<6>::fromCovariance(covariance, "PriorBiasFactor: covariance"),
                      std::move(loss)) {}

PriorBiasFactor::PriorBiasFactor(Key key, const ImuBias& prior, const Vec6& sigmas, RobustLossPtr loss)
    : PriorBiasFactor(key, prior, SqrtInformation<6>::fromSigmas(sigmas, "PriorBiasFactor: sigmas"),
                      std::move(loss)) {}

void PriorBiasFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  r = sqrt_info_ * prior_.local(x.bias(keys()[0]));
  if (H != nullptr) (*H)[0] = sqrt_info_;
}

// ---------------------------------------------------------------------------
HeightBandFactor::HeightBandFactor(Key pose_key, double z_min_m, double z_max_m, double sigma_m, RobustLossPtr loss)
    : Factor({pose_key}, std::move(loss)),
      z_min_m_(z_min_m),
      z_max_m_(z_max_m),
      sigma_m_(sigma_m),
      inv_sigma_(1.0 / sigma_m) {
  if (!std::isfinite(z_min_m)) throw std::invalid_argument("HeightBandFactor: z_min_m must be finite");
  if (!std::isfinite(z_max_m)) throw std::invalid_argument("HeightBandFactor: z_max_m must be finite");
  if (z_min_m > z_max_m) {
    throw std::invalid_argument("HeightBandFactor: z_min_m (" + std::to_string(z_min_m) + ") must not exceed z_max_m (" +
                                std::to_string(z_max_m) + ")");
  }
  if (!(std::isfinite(sigma_m) && sigma_m > 0.0)) {
    throw std::invalid_argument("HeightBandFactor: sigma_m must be positive and finite, got " + std::to_string(sigma_m));
  }
}

void HeightBandFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Pose3& T_w_b = x.pose(keys()[0]);
  const double z_m = T_w_b.p.z();
  double excess_m = 0.0;  // signed distance outside the band
  if (z_m > z_max_m_) {
    excess_m = z_m - z_max_m_;
  } else if (z_m < z_min_m_) {
    excess_m = z_m - z_min_m_;
  }
  r.resize(1);
  r(0) = excess_m * inv_sigma_;
  if (H == nullptr) return;
  // dz/d[phi; rho] = [0, e_z^T R] (p' = p + R rho); zero inside the band.
  JacobianBlock& J_r_pose = (*H)[0];
  J_r_pose.setZero(1, 6);
  // An equality band (the height hold) is a plain prior: its information
  // stays in the linearization at its own centre too.
  if (excess_m != 0.0 || z_min_m_ == z_max_m_) J_r_pose.rightCols<3>() = inv_sigma_ * T_w_b.R.row(2);
}

}  // namespace rilo
