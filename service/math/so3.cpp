#include "math/so3.h"

#include <cmath>

namespace rilo::so3 {
namespace {
// Below this angle (rad) the closed forms lose precision; use Taylor series.
constexpr double kSmallAngle = 1e-5;
}  // namespace

Mat3 hat(const Vec3& a) {
  Mat3 S;
  S << 0.0, -a.z(), a.y(), a.z(), 0.0, -a.x(), -a.y(), a.x(), 0.0;
  return S;
}

Mat3 exp(const Vec3& phi) {
  const double theta2 = phi.squaredNorm();
  const double theta = std::sqrt(theta2);
  const Mat3 W = hat(phi);
  double a, b;  // R = I + a W + b W^2
  if (theta < kSmallAngle) {
    a = 1.0 - theta2 / 6.0;
    b = 0.5 - theta2 / 24.0;
  } else {
    const double s_half = std::sin(0.5 * theta);
    a = std::sin(theta) / theta;
    b = 2.0 * s_half * s_half / theta2;  // (1 - cos) / theta^2 without cancellation
  }
  return Mat3::Identity() + a * W + b * W * W;
}

Vec3 log(const Mat3& R) {
  // Quaternion route: stable for all angles including near pi.
  Quat q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() *= -1.0;  // shortest rotation, angle in [0, pi]
  const Vec3 v = q.vec();
  const double s = v.norm();
  if (s < 1e-10) {
    // theta ~= 2 s; phi = 2 v / w * (1 - s^2/(3 w^2))
    const double w = q.w();
    return (2.0 / w) * (1.0 - s * s / (3.0 * w * w)) * v;
  }
  const double theta = 2.0 * std::atan2(s, q.w());
  return (theta / s) * v;
}

Mat3 rightJacobian(const Vec3& phi) {
  const double theta2 = phi.squaredNorm();
  const double theta = std::sqrt(theta2);
  const Mat3 W = hat(phi);
  double a, b;  // Jr = I - a W + b W^2
  if (theta < kSmallAngle) {
    a = 0.5 - theta2 / 24.0;
    b = 1.0 / 6.0 - theta2 / 120.0;
  } else {
    const double s_half = std::sin(0.5 * theta);
    a = 2.0 * s_half * s_half / theta2;  // (1 - cos) / theta^2 without cancellation
    b = (theta - std::sin(theta)) / (theta2 * theta);
  }
  return Mat3::Identity() - a * W + b * W * W;
}

Mat3 rightJacobianInverse(const Vec3& phi) {
  const double theta2 = phi.squaredNorm();
  const double theta = std::sqrt(theta2);
  const Mat3 W = hat(phi);
  double b;  // Jr^-1 = I + W/2 + b W^2
  if (theta < kSmallAngle) {
    b = 1.0 / 12.0 + theta2 / 720.0;
  } else {
    b = 1.0 / theta2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  }
  return Mat3::Identity() + 0.5 * W + b * W * W;
}

Mat3 normalize(const Mat3& R) { return Quat(R).normalized().toRotationMatrix(); }

}  // namespace rilo::so3
