#pragma once
// Unary priors on Pose3, Vec3 (velocity, anchor position) and ImuBias, and a
// soft height band on the body height.
//
// Priors whiten with an upper-triangular square-root information matrix U,
// U^T U = covariance^-1 (U = chol(information)^T, as GTSAM's R), stored as a
// fixed-size matrix so evaluation never allocates:
//   PriorPose3Factor: r = U * local(T_prior, T) = U * [Log(R_p^T R); R_p^T (p - p_p)]
//   PriorVec3Factor:  r = U * (x - x_prior)
//   PriorBiasFactor:  r = U * (b - b_prior)           (accel then gyro)
// Jacobian of the pose prior w.r.t. the tangent [phi; rho] of T
// (R' = R Exp(phi), p' = p + R rho):
//   d Log(R_p^T R Exp(phi)) / d phi = Jr^-1(Log(R_p^T R));  d R_p^T (p + R rho - p_p) / d rho = R_p^T R
// with no cross terms, so J = U * [Jr^-1(phi) 0; 0 R_p^T R].
//
// Noise can be given as a covariance (checked: finite, symmetric, positive
// definite) or as per-axis standard deviations (checked: positive, finite);
// both throw std::invalid_argument naming the parameter. Pass concrete
// VecN/MatN objects: an unevaluated Eigen expression converts to both and the
// overload is ambiguous (or use SqrtInformation<N>::from...()).
//
// Robust losses: the vector priors (pose, Vec3, bias) accept only symmetric
// losses (rho(|r|) is applied to the whole residual); an asymmetric one throws
// std::invalid_argument. HeightBandFactor is scalar and takes any loss.
#include <string_view>

#include "estimation/graph/factor.h"

namespace rilo {

/// Upper-triangular square-root information U (U^T U = covariance^-1) of an N-dim Gaussian.
template <int N>
struct SqrtInformation {
  using Matrix = Eigen::Matrix<double, N, N>;
  using Vector = Eigen::Matrix<double, N, 1>;

  Matrix U = Matrix::Identity();  ///< upper triangular, units 1/(residual unit)

  /// Throws std::invalid_argument (message names `what`) unless cov is finite,
  /// symmetric (relative tolerance 1e-9) and numerically positive definite
  /// (Cholesky pivots above 1e-12 of the largest diagonal entry).
  static SqrtInformation fromCovariance(const Matrix& cov, std::string_view what = "covariance");
  /// Diagonal U = diag(1/sigma); throws std::invalid_argument unless every sigma is positive and finite.
  static SqrtInformation fromSigmas(const Vector& sigmas, std::string_view what = "sigmas");
};

extern template struct SqrtInformation<1>;
extern template struct SqrtInformation<3>;
extern template struct SqrtInformation<6>;

/// Prior on a Pose3 T_w_b (6-dim residual, rotation first).
class PriorPose3Factor final : public Factor {
 public:
  PriorPose3Factor(Key key, const Pose3& T_prior, const SqrtInformation<6>& noise, RobustLossPtr loss = nullptr);
  /// covariance of [phi; rho] (rad^2, m^2), 6x6 SPD.
  PriorPose3Factor(Key key, const Pose3& T_prior, const Mat6& covariance, RobustLossPtr loss = nullptr);
  /// sigmas of [phi; rho] (rad, m), all > 0.
  PriorPose3Factor(Key key, const Pose3& T_prior, const Vec6& sigmas, RobustLossPtr loss = nullptr);

  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  const Pose3& prior() const { return T_prior_; }
  const Mat6& sqrtInformation() const { return sqrt_info_; }

 private:
  Pose3 T_prior_;   ///< prior mean T_w_b
  Mat6 sqrt_info_;  ///< upper-triangular sqrt information of [phi; rho]
};

/// Prior on a Vec3 variable: velocity v_w_b (m/s) or anchor position p_w_anchor (m).
class PriorVec3Factor final : public Factor {
 public:
  PriorVec3Factor(Key key, const Vec3& prior, const SqrtInformation<3>& noise, RobustLossPtr loss = nullptr);
  /// 3x3 SPD covariance (unit^2).
  PriorVec3Factor(Key key, const Vec3& prior, const Mat3& covariance, RobustLossPtr loss = nullptr);
  /// per-axis sigmas (unit), all > 0.
  PriorVec3Factor(Key key, const Vec3& prior, const Vec3& sigmas, RobustLossPtr loss = nullptr);

  int dim() const override { return 3; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  const Vec3& prior() const { return prior_; }
  const Mat3& sqrtInformation() const { return sqrt_info_; }

 private:
  Vec3 prior_;      ///< prior mean (world frame)
  Mat3 sqrt_info_;  ///< upper-triangular sqrt information
};

/// Prior on an ImuBias (6-dim residual: accel (m/s^2) then gyro (rad/s)).
class PriorBiasFactor final : public Factor {
 public:
  PriorBiasFactor(Key key, const ImuBias& prior, const SqrtInformation<6>& noise, RobustLossPtr loss = nullptr);
  /// 6x6 SPD covariance of [b_a; b_g].
  PriorBiasFactor(Key key, const ImuBias& prior, const Mat6& covariance, RobustLossPtr loss = nullptr);
  /// sigmas of [b_a; b_g], all > 0.
  PriorBiasFactor(Key key, const ImuBias& prior, const Vec6& sigmas, RobustLossPtr loss = nullptr);

  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  const ImuBias& prior() const { return prior_; }
  const Mat6& sqrtInformation() const { return sqrt_info_; }

 private:
  ImuBias prior_;   ///< prior mean
  Mat6 sqrt_info_;  ///< upper-triangular sqrt information
};

/// Soft band on the body height z = p_w_b.z() (m), for poor vertical geometry
/// (anchors at similar heights): zero inside [z_min, z_max], and outside
///   r = (z - z_max) / sigma  above the band (r > 0),
///   r = (z - z_min) / sigma  below the band (r < 0),
/// so the cost grows quadratically with the distance to the band. r is
/// continuous (not C1: its slope jumps at the edges, which Gauss-Newton
/// tolerates). z_min == z_max gives a soft height equality: a Gaussian prior
/// on z, whose Jacobian is kept at its centre too (the stream's height hold).
class HeightBandFactor final : public Factor {
 public:
  /// Throws std::invalid_argument on non-finite bounds, z_min_m > z_max_m or sigma_m <= 0.
  HeightBandFactor(Key pose_key, double z_min_m, double z_max_m, double sigma_m, RobustLossPtr loss = nullptr);

  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  double zMin() const { return z_min_m_; }    ///< lower band edge (m, world z)
  double zMax() const { return z_max_m_; }    ///< upper band edge (m, world z)
  double sigma() const { return sigma_m_; }   ///< softness outside the band (m)

 private:
  double z_min_m_;    ///< lower edge (m)
  double z_max_m_;    ///< upper edge (m)
  double sigma_m_;    ///< std-dev scale outside the band (m)
  double inv_sigma_;  ///< 1 / sigma_m_ (1/m)
};

}  // namespace rilo
