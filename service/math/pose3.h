#pragma once
// Rigid body pose T_w_b (world-from-body) with the retraction used by every
// factor and smoother in rilo:
//   T (+) [phi; rho] = (R Exp(phi), p + R rho)        tangent order: rotation first
//   local(T_a, T_b)  = [Log(R_a^T R_b); R_a^T (p_b - p_a)]
// local() is the exact inverse of retract(), so numerical and analytic
// Jacobians are taken in the same chart.
#include "math/so3.h"

namespace rilo {

struct Pose3 {
  Mat3 R = Mat3::Identity();  ///< rotation world-from-body
  Vec3 p = Vec3::Zero();      ///< body origin in world (m)

  static constexpr int kDim = 6;

  Pose3() = default;
  Pose3(const Mat3& R_w_b, const Vec3& p_w_b) : R(R_w_b), p(p_w_b) {}
  Pose3(const Quat& q_w_b, const Vec3& p_w_b) : R(q_w_b.normalized().toRotationMatrix()), p(p_w_b) {}

  Pose3 retract(const Vec6& xi) const {
    return Pose3(R * so3::exp(xi.head<3>()), p + R * xi.tail<3>());
  }
  Vec6 local(const Pose3& other) const {
    Vec6 xi;
    xi.head<3>() = so3::log(R.transpose() * other.R);
    xi.tail<3>() = R.transpose() * (other.p - p);
    return xi;
  }
  /// SE(3) group exponential of xi = [phi; rho]: (Exp(phi), Jl(phi) rho) with the
  /// left Jacobian Jl(phi) = Jr(-phi). (The retraction above is the cheaper
  /// SO(3) x R^3 chart; expmap/logmap serve interpolation and extrapolation
  /// along constant body twists.)
  static Pose3 expmap(const Vec6& xi) {
    const Vec3 phi = xi.head<3>();
    return Pose3(so3::exp(phi), so3::rightJacobian(-phi) * xi.tail<3>());
  }
  /// Inverse of expmap: [Log(R); Jl(phi)^-1 p].
  static Vec6 logmap(const Pose3& T) {
    Vec6 xi;
    xi.head<3>() = so3::log(T.R);
    xi.tail<3>() = so3::rightJacobianInverse(-xi.head<3>().eval()) * T.p;
    return xi;
  }
  Pose3 compose(const Pose3& other) const { return Pose3(R * other.R, R * other.p + p); }
  Pose3 inverse() const { return Pose3(R.transpose(), -(R.transpose() * p)); }

  /// Point in body frame -> world frame.
  Vec3 transformFrom(const Vec3& p_b) const { return R * p_b + p; }
  Quat quaternion() const { return Quat(R).normalized(); }
};

}  // namespace rilo
