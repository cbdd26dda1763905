#include "dds/conversions.h"

#include <algorithm>
#include <array>
#include <cstring>
#include <utility>

namespace rilo::dds {
namespace {

constexpr std::int64_t kNsPerS = 1'000'000'000;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

void putPose(const Eigen::Vector3d& p, const Eigen::Quaterniond& q, geometry_msgs_msg_dds__Pose_& pose) noexcept {
  pose.position.x = p.x();
  pose.position.y = p.y();
  pose.position.z = p.z();
  pose.orientation.x = q.x();
  pose.orientation.y = q.y();
  pose.orientation.z = q.z();
  pose.orientation.w = q.w();
}

void getPose(const geometry_msgs_msg_dds__Pose_& pose, Eigen::Vector3d& p, Eigen::Quaterniond& q) noexcept {
  p = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  q = Eigen::Quaterniond(pose.orientation.w, pose.orientation.x, pose.orientation.y, pose.orientation.z);
}

void putVector(const Eigen::Vector3d& v, geometry_msgs_msg_dds__Vector3_& out) noexcept {
  out.x = v.x();
  out.y = v.y();
  out.z = v.z();
}

Eigen::Vector3d getVector(const geometry_msgs_msg_dds__Vector3_& v) noexcept { return {v.x, v.y, v.z}; }

std::string stringOf(const char* s) { return s != nullptr ? std::string(s) : std::string(); }

/// A received C string into a fixed NUL-terminated array (truncated; null reads as empty).
template <std::size_t N>
void copyString(const char* src, std::array<char, N>& dst) noexcept {
  const std::size_t n = src != nullptr ? std::min(std::strlen(src), N - 1) : 0;
  if (n > 0) std::memcpy(dst.data(), src, n);
  dst[n] = '\0';
}

}  // namespace

void toRosTime(std::int64_t t_ns, builtin_interfaces_msg_dds__Time_& stamp) noexcept {
  std::int64_t sec = t_ns / kNsPerS;
  std::int64_t nsec = t_ns % kNsPerS;
  if (nsec < 0) {  // floor, so nanosec stays in [0, 1e9) before the epoch too
    nsec += kNsPerS;
    --sec;
  }
  stamp.sec = static_cast<std::int32_t>(sec);
  stamp.nanosec = static_cast<std::uint32_t>(nsec);
}

std::int64_t fromRosTime(const builtin_interfaces_msg_dds__Time_& stamp) noexcept {
  return static_cast<std::int64_t>(stamp.sec) * kNsPerS + static_cast<std::int64_t>(stamp.nanosec);
}

namespace {

// J P J^T with J = diag(I, R), by blocks (a third of the dense 6x6 product).
Mat6 rosPoseCovariance(const Eigen::Matrix3d& R_w_b, const Mat6& P) noexcept {
  Mat6 out;
  out.topLeftCorner<3, 3>() = P.topLeftCorner<3, 3>();
  out.topRightCorner<3, 3>().noalias() = P.topRightCorner<3, 3>() * R_w_b.transpose();
  out.bottomLeftCorner<3, 3>() = out.topRightCorner<3, 3>().transpose();
  out.bottomRightCorner<3, 3>().noalias() = R_w_b * P.bottomRightCorner<3, 3>() * R_w_b.transpose();
  return out;
}

BodyTwist bodyTwist(const Eigen::Matrix3d& R_w_b, const NavigationState& state) noexcept {
  BodyTwist twist;
  twist.v_b.noalias() = R_w_b.transpose() * state.v_w_b;
  twist.omega_b = state.omega_b;
  const Eigen::Matrix3d J_vb_theta = skew(twist.v_b);
  const Mat6& P = state.twist_covariance;
  twist.covariance.topLeftCorner<3, 3>().noalias() = R_w_b.transpose() * P.topLeftCorner<3, 3>() * R_w_b;
  twist.covariance.topLeftCorner<3, 3>().noalias() +=
      J_vb_theta * state.pose_covariance.bottomRightCorner<3, 3>() * J_vb_theta.transpose();
  twist.covariance.topRightCorner<3, 3>().noalias() = R_w_b.transpose() * P.topRightCorner<3, 3>();
  twist.covariance.bottomLeftCorner<3, 3>().noalias() = P.bottomLeftCorner<3, 3>() * R_w_b;
  twist.covariance.bottomRightCorner<3, 3>() = P.bottomRightCorner<3, 3>();
  return twist;
}

}  // namespace

Mat6 rosPoseCovariance(const NavigationState& state) noexcept {
  return rosPoseCovariance(state.q_w_b.normalized().toRotationMatrix(), state.pose_covariance);
}

BodyTwist bodyTwist(const NavigationState& state) noexcept {
  return bodyTwist(state.q_w_b.normalized().toRotationMatrix(), state);
}

const char* trackingStateName(TrackingState state) noexcept {
  switch (state) {
    case TrackingState::kInitializing: return "initializing";
    case TrackingState::kTracking: return "tracking";
    case TrackingState::kDegraded: return "degraded";
    case TrackingState::kLost: return "lost";
  }
  return "unknown";
}

void toRowMajor(const Mat6& covariance, double (&out)[36]) noexcept {
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) out[6 * r + c] = covariance(r, c);
  }
}

Mat6 fromRowMajor(const double (&in)[36]) noexcept {
  Mat6 m;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) m(r, c) = in[6 * r + c];
  }
  return m;
}

void fillOdometry(const NavigationState& state, nav_msgs_msg_dds__Odometry_& msg, std::int64_t stamp_offset_ns) noexcept {
  const Eigen::Quaterniond q_w_b = state.q_w_b.normalized();
  const Eigen::Matrix3d R_w_b = q_w_b.toRotationMatrix();
  toRosTime(state.t_ns + stamp_offset_ns, msg.header.stamp);
  putPose(state.p_w_b, q_w_b, msg.pose.pose);
  toRowMajor(rosPoseCovariance(R_w_b, state.pose_covariance), msg.pose.covariance);
  const BodyTwist twist = bodyTwist(R_w_b, state);
  putVector(twist.v_b, msg.twist.twist.linear);
  putVector(twist.omega_b, msg.twist.twist.angular);
  toRowMajor(twist.covariance, msg.twist.covariance);
}

void fillPose(const NavigationState& state, geometry_msgs_msg_dds__PoseWithCovarianceStamped_& msg,
              std::int64_t stamp_offset_ns) noexcept {
  const Eigen::Quaterniond q_w_b = state.q_w_b.normalized();
  toRosTime(state.t_ns + stamp_offset_ns, msg.header.stamp);
  putPose(state.p_w_b, q_w_b, msg.pose.pose);
  toRowMajor(rosPoseCovariance(q_w_b.toRotationMatrix(), state.pose_covariance), msg.pose.covariance);
}

void fillTransform(const NavigationState& state, geometry_msgs_msg_dds__TransformStamped_& msg,
                   std::int64_t stamp_offset_ns) noexcept {
  const Eigen::Quaterniond q_w_b = state.q_w_b.normalized();
  toRosTime(state.t_ns + stamp_offset_ns, msg.header.stamp);
  putVector(state.p_w_b, msg.transform.translation);
  msg.transform.rotation.x = q_w_b.x();
  msg.transform.rotation.y = q_w_b.y();
  msg.transform.rotation.z = q_w_b.z();
  msg.transform.rotation.w = q_w_b.w();
}

void fillStatus(const ServiceStatus& status, rilo_msg_dds__Status_& msg, std::int64_t stamp_offset_ns) noexcept {
  toRosTime(status.t_ns + stamp_offset_ns, msg.header.stamp);
  msg.monotonic_ns = status.t_ns;
  msg.state = static_cast<std::uint8_t>(status.state);
  msg.imu_samples = status.imu_samples;
  msg.range_samples = status.range_samples;
  msg.tdoa_samples = status.tdoa_samples;
  msg.ultrasonic_samples = status.ultrasonic_samples;
  msg.queue_overflows = status.queue_overflows;
  msg.late_updates = status.late_updates;
  msg.sensor_faults = status.sensor_faults;
  msg.sensor_silences = status.sensor_silences;
  msg.reinitializations = status.reinitializations;
  msg.rejected_ranges = status.rejected_ranges;
  msg.deep_nlos_tdoa_rows = status.deep_nlos_tdoa_rows;
  msg.published_odometry = status.published_odometry;
  msg.non_finite_samples = status.non_finite_samples;
  msg.duplicate_samples = status.duplicate_samples;
  msg.out_of_order_samples = status.out_of_order_samples;
  msg.imu_gaps = status.imu_gaps;
  msg.ranging_gaps = status.ranging_gaps;
  msg.out_of_bounds_samples = status.out_of_bounds_samples;
  msg.beyond_full_scale_samples = status.beyond_full_scale_samples;
  msg.far_future_samples = status.far_future_samples;
  msg.time_jumps = status.time_jumps;
  msg.last_update_ms = status.last_update_ms;
  msg.mean_update_ms = status.mean_update_ms;
  msg.max_update_ms = status.max_update_ms;
  msg.p99_update_ms = status.p99_update_ms;
  msg.estimator_queue_high_water = status.estimator_queue_high_water;
  msg.publisher_queue_high_water = status.publisher_queue_high_water;
  msg.last_cliques_reeliminated = status.last_cliques_reeliminated;
  msg.last_relinearized = status.last_relinearized;
  msg.last_lambda = status.last_lambda;
  msg.odometry_latency_ms = status.odometry_latency_ms;
  msg.pose_latency_ms = status.pose_latency_ms;
}

OdometryMessage toOdometryMessage(const nav_msgs_msg_dds__Odometry_& msg) {
  OdometryMessage out;
  out.stamp_ns = fromRosTime(msg.header.stamp);
  out.frame_id = stringOf(msg.header.frame_id);
  out.child_frame_id = stringOf(msg.child_frame_id);
  getPose(msg.pose.pose, out.p_w_b, out.q_w_b);
  out.pose_covariance = fromRowMajor(msg.pose.covariance);
  out.v_b = getVector(msg.twist.twist.linear);
  out.omega_b = getVector(msg.twist.twist.angular);
  out.twist_covariance = fromRowMajor(msg.twist.covariance);
  return out;
}

PoseMessage toPoseMessage(const geometry_msgs_msg_dds__PoseWithCovarianceStamped_& msg) {
  PoseMessage out;
  out.stamp_ns = fromRosTime(msg.header.stamp);
  out.frame_id = stringOf(msg.header.frame_id);
  getPose(msg.pose.pose, out.p_w_b, out.q_w_b);
  out.covariance = fromRowMajor(msg.pose.covariance);
  return out;
}

StatusMessage toStatusMessage(const rilo_msg_dds__Status_& msg) {
  StatusMessage out;
  out.stamp_ns = fromRosTime(msg.header.stamp);
  ServiceStatus& s = out.status;
  s.t_ns = msg.monotonic_ns;
  s.state = static_cast<TrackingState>(msg.state);
  s.imu_samples = msg.imu_samples;
  s.range_samples = msg.range_samples;
  s.tdoa_samples = msg.tdoa_samples;
  s.ultrasonic_samples = msg.ultrasonic_samples;
  s.queue_overflows = msg.queue_overflows;
  s.late_updates = msg.late_updates;
  s.sensor_faults = msg.sensor_faults;
  s.sensor_silences = msg.sensor_silences;
  s.reinitializations = msg.reinitializations;
  s.rejected_ranges = msg.rejected_ranges;
  s.deep_nlos_tdoa_rows = msg.deep_nlos_tdoa_rows;
  s.published_odometry = msg.published_odometry;
  s.non_finite_samples = msg.non_finite_samples;
  s.duplicate_samples = msg.duplicate_samples;
  s.out_of_order_samples = msg.out_of_order_samples;
  s.imu_gaps = msg.imu_gaps;
  s.ranging_gaps = msg.ranging_gaps;
  s.out_of_bounds_samples = msg.out_of_bounds_samples;
  s.beyond_full_scale_samples = msg.beyond_full_scale_samples;
  s.far_future_samples = msg.far_future_samples;
  s.time_jumps = msg.time_jumps;
  s.last_update_ms = msg.last_update_ms;
  s.mean_update_ms = msg.mean_update_ms;
  s.max_update_ms = msg.max_update_ms;
  s.p99_update_ms = msg.p99_update_ms;
  s.estimator_queue_high_water = msg.estimator_queue_high_water;
  s.publisher_queue_high_water = msg.publisher_queue_high_water;
  s.last_cliques_reeliminated = msg.last_cliques_reeliminated;
  s.last_relinearized = msg.last_relinearized;
  s.last_lambda = msg.last_lambda;
  s.odometry_latency_ms = msg.odometry_latency_ms;
  s.pose_latency_ms = msg.pose_latency_ms;
  copyString(msg.last_fault, s.last_fault);
  copyString(msg.reason, s.reason);
  out.state_name = stringOf(msg.state_name);
  return out;
}

RangesMessage toRangesMessage(const rilo_msg_dds__Ranges_& msg) {
  RangesMessage out;
  out.stamp_ns = fromRosTime(msg.header.stamp);
  out.frame_id = stringOf(msg.header.frame_id);
  out.ranges.reserve(msg.ranges._length);
  for (std::uint32_t i = 0; i < msg.ranges._length; ++i) {
    const rilo_msg_dds__RangeReading_& r = msg.ranges._buffer[i];
    out.ranges.push_back({r.anchor_id, r.range_m, r.predicted_m, r.residual_m, r.weight, r.nlos, r.t_offset_ns});
  }
  return out;
}

TfMessage toTfMessage(const tf2_msgs_msg_dds__TFMessage_& msg) {
  TfMessage out;
  out.transforms.reserve(msg.transforms._length);
  for (std::uint32_t i = 0; i < msg.transforms._length; ++i) {
    const geometry_msgs_msg_dds__TransformStamped_& t = msg.transforms._buffer[i];
    TransformMessage m;
    m.stamp_ns = fromRosTime(t.header.stamp);
    m.frame_id = stringOf(t.header.frame_id);
    m.child_frame_id = stringOf(t.child_frame_id);
    m.translation = getVector(t.transform.translation);
    m.rotation = Eigen::Quaterniond(t.transform.rotation.w, t.transform.rotation.x, t.transform.rotation.y,
                                    t.transform.rotation.z);
    out.transforms.push_back(std::move(m));
  }
  return out;
}

}  // namespace rilo::dds
