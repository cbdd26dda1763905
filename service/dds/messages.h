#pragma once
// Received rilo messages as C++ values (the reader side: `rilo listen`,
// tests). Conventions are those of the ROS messages on the wire (see
// conversions.h): pose covariance rotation about the world axes, twist in the
// body frame.
#include <cstdint>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "runtime/service_status.h"

namespace rilo::dds {

using Mat6 = Eigen::Matrix<double, 6, 6>;

struct OdometryMessage {
  std::int64_t stamp_ns = 0;             ///< header.stamp (ns, on the service's dds.stamp_clock: system time by default)
  std::int64_t source_timestamp_ns = 0;  ///< DDS source timestamp of the sample (rilo writes stamp_ns)
  std::string frame_id;                  ///< world frame
  std::string child_frame_id;            ///< body frame
  Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_w_b = Eigen::Quaterniond::Identity();
  Mat6 pose_covariance = Mat6::Zero();   ///< (p_w, rotation about world axes)
  Eigen::Vector3d v_b = Eigen::Vector3d::Zero();      ///< body velocity in the body frame (m/s)
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  ///< body rate in the body frame (rad/s)
  Mat6 twist_covariance = Mat6::Zero();  ///< (v_b, omega_b)
};

struct PoseMessage {
  std::int64_t stamp_ns = 0;
  std::int64_t source_timestamp_ns = 0;
  std::string frame_id;                  ///< world frame
  Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();
  Eigen::Quaterniond q_w_b = Eigen::Quaterniond::Identity();
  Mat6 covariance = Mat6::Zero();        ///< (p_w, rotation about world axes)
};

struct StatusMessage {
  std::int64_t stamp_ns = 0;             ///< header.stamp (dds.stamp_clock)
  std::int64_t source_timestamp_ns = 0;
  ServiceStatus status;                  ///< status.t_ns = monotonic_ns: the same instant on rilo's clock
  std::string state_name;
};

/// One rilo_msgs/RangeReading.
struct RangeReading {
  std::uint32_t anchor_id = 0;
  double range_m = 0.0;
  double predicted_m = 0.0;
  double residual_m = 0.0;
  double weight = 1.0;
  bool nlos = false;
  std::int64_t t_offset_ns = 0;  ///< the range's time minus the message's stamp (>= 0)
};

/// One rilo_msgs/Ranges: a ranging epoch's ranges as the estimator judged them.
struct RangesMessage {
  std::int64_t stamp_ns = 0;
  std::int64_t source_timestamp_ns = 0;
  std::string frame_id;
  std::vector<RangeReading> ranges;
};

/// One geometry_msgs/TransformStamped: the pose of child_frame_id in frame_id.
struct TransformMessage {
  std::int64_t stamp_ns = 0;
  std::string frame_id;                  ///< parent (world)
  std::string child_frame_id;            ///< child (body)
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
};

/// One tf2_msgs/TFMessage.
struct TfMessage {
  std::int64_t source_timestamp_ns = 0;
  std::vector<TransformMessage> transforms;
};

}  // namespace rilo::dds
