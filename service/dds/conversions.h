#pragma once
// rilo values <-> ROS 2 shaped DDS samples (idl/), frames per REP-103/105.
//
// Time: header.stamp and the DDS source timestamp both carry the state's t_ns
// (rilo's one clock: CLOCK_MONOTONIC on the device, the recording's clock in
// replay) plus `stamp_offset_ns`: the publisher's tracked system-minus-
// monotonic offset with dds.stamp_clock: system (stamp_clock.h), 0 with
// monotonic. sec = floor(stamp / 1e9), nanosec the remainder.
//
// Pose covariance: NavigationState perturbs the rotation in the body frame,
// R_w_b' = R_w_b Exp(dtheta_b); ROS defines the rotation part about the fixed
// axes of header.frame_id, R_w_b' = Exp(dtheta_w) R_w_b, so dtheta_w =
// R_w_b dtheta_b and the published covariance is J P J^T with
// J = diag(I3, R_w_b) (position rows stay in world).
//
// Odometry twist (REP-105: in child_frame_id, the body): v_b = R_w_b^T v_w_b.
// To first order dv_b = R_w_b^T dv_w + [v_b]x dtheta_b, so
//   cov(v_b)         = R^T cov(v_w) R + [v_b]x cov(theta_b) [v_b]x^T
//   cov(v_b, omega)  = R^T cov(v_w, omega)
//   cov(omega)       unchanged (already in the body frame),
// with cov(theta_b) the rotation block of the pose covariance. NavigationState
// carries no velocity-attitude cross-covariance, so those two are taken as
// independent (the attitude term only matters when moving fast with a poor
// heading).
//
// The fill functions write numbers only: string members (frame ids, state
// name, fault) are pointed at caller-owned storage once (publisher.h), so
// filling never allocates.
#include <cstdint>

#include "dds/messages.h"
#include "geometry_msgs.h"
#include "nav_msgs.h"
#include "rilo_msgs.h"
#include "tf2_msgs.h"
#include "runtime/navigation_state.h"
#include "runtime/service_status.h"

namespace rilo::dds {

void toRosTime(std::int64_t t_ns, builtin_interfaces_msg_dds__Time_& stamp) noexcept;
std::int64_t fromRosTime(const builtin_interfaces_msg_dds__Time_& stamp) noexcept;

/// Pose covariance in the ROS convention (see above).
Mat6 rosPoseCovariance(const NavigationState& state) noexcept;

struct BodyTwist {
  Eigen::Vector3d v_b = Eigen::Vector3d::Zero();      ///< m/s, body frame
  Eigen::Vector3d omega_b = Eigen::Vector3d::Zero();  ///< rad/s, body frame
  Mat6 covariance = Mat6::Zero();                     ///< (v_b, omega_b)
};
/// Twist in the body frame with its covariance (see above).
BodyTwist bodyTwist(const NavigationState& state) noexcept;

/// Lower-case name of a tracking state ("initializing", "tracking", "degraded", "lost").
const char* trackingStateName(TrackingState state) noexcept;

/// Row-major 6x6 covariance (ROS layout) <-> Eigen.
void toRowMajor(const Mat6& covariance, double (&out)[36]) noexcept;
Mat6 fromRowMajor(const double (&in)[36]) noexcept;

void fillOdometry(const NavigationState& state, nav_msgs_msg_dds__Odometry_& msg,
                  std::int64_t stamp_offset_ns = 0) noexcept;
void fillPose(const NavigationState& state, geometry_msgs_msg_dds__PoseWithCovarianceStamped_& msg,
              std::int64_t stamp_offset_ns = 0) noexcept;
/// The body's pose in the world as a transform (stamp, translation, rotation;
/// the frame ids are the caller's).
void fillTransform(const NavigationState& state, geometry_msgs_msg_dds__TransformStamped_& msg,
                   std::int64_t stamp_offset_ns = 0) noexcept;
/// Everything but the strings state_name and last_fault; header.stamp =
/// t_ns + stamp_offset_ns, monotonic_ns = t_ns.
void fillStatus(const ServiceStatus& status, rilo_msg_dds__Status_& msg, std::int64_t stamp_offset_ns = 0) noexcept;

OdometryMessage toOdometryMessage(const nav_msgs_msg_dds__Odometry_& msg);
PoseMessage toPoseMessage(const geometry_msgs_msg_dds__PoseWithCovarianceStamped_& msg);
StatusMessage toStatusMessage(const rilo_msg_dds__Status_& msg);
RangesMessage toRangesMessage(const rilo_msg_dds__Ranges_& msg);
TfMessage toTfMessage(const tf2_msgs_msg_dds__TFMessage_& msg);

}  // namespace rilo::dds
