#pragma once
// IMU bias variable: accelerometer then gyroscope (GTSAM's order), vector space.
#include "math/types.h"

namespace rilo {

struct ImuBias {
  Vec3 accel = Vec3::Zero();  ///< accelerometer bias (m/s^2), body frame
  Vec3 gyro = Vec3::Zero();   ///< gyroscope bias (rad/s), body frame

  static constexpr int kDim = 6;

  ImuBias() = default;
  ImuBias(const Vec3& b_a, const Vec3& b_g) : accel(b_a), gyro(b_g) {}
  explicit ImuBias(const Vec6& v) : accel(v.head<3>()), gyro(v.tail<3>()) {}

  Vec6 vector() const {
    Vec6 v;
    v << accel, gyro;
    return v;
  }
  ImuBias retract(const Vec6& d) const { return ImuBias(accel + d.head<3>(), gyro + d.tail<3>()); }
  Vec6 local(const ImuBias& other) const { return other.vector() - vector(); }
};

}  // namespace rilo
