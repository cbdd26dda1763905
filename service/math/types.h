#pragma once
// Fixed-size Eigen aliases used throughout the estimation library.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace rilo {

using Vec3 = Eigen::Vector3d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Vec9 = Eigen::Matrix<double, 9, 1>;
using Vec15 = Eigen::Matrix<double, 15, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Mat9 = Eigen::Matrix<double, 9, 9>;
using Mat15 = Eigen::Matrix<double, 15, 15>;
using Mat93 = Eigen::Matrix<double, 9, 3>;
using Quat = Eigen::Quaterniond;

}  // namespace rilo
