#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <random>

#include "dds/conversions.h"
#include "dds_test_support.h"

namespace rilo::dds {
namespace {

using testing::randomCovariance;
using testing::randomState;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;

Mat3 expSo3(const Vec3& phi) {
  const double angle = phi.norm();
  if (angle < 1e-300) return Mat3::Identity();
  return Eigen::AngleAxisd(angle, phi / angle).toRotationMatrix();
}

Vec3 logSo3(const Mat3& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

/// Central-difference Jacobian of f: R^n -> R^m at 0.
template <int M, int N>
Eigen::Matrix<double, M, N> numericalJacobian(const std::function<Eigen::Matrix<double, M, 1>(const Eigen::Matrix<double, N, 1>&)>& f) {
  constexpr double h = 1e-6;
  Eigen::Matrix<double, M, N> J;
  for (int i = 0; i < N; ++i) {
    Eigen::Matrix<double, N, 1> d = Eigen::Matrix<double, N, 1>::Zero();
    d(i) = h;
    J.col(i) = (f(d) - f(-d)) / (2.0 * h);
  }
  return J;
}

TEST(DdsRosTime, SplitsNanosecondsWithFloor) {
  builtin_interfaces_msg_dds__Time_ t{};
  toRosTime(0, t);
  EXPECT_EQ(t.sec, 0);
  EXPECT_EQ(t.nanosec, 0u);
  toRosTime(1'234'567'890'123, t);
  EXPECT_EQ(t.sec, 1234);
  EXPECT_EQ(t.nanosec, 567'890'123u);
  toRosTime(999'999'999, t);
  EXPECT_EQ(t.sec, 0);
  EXPECT_EQ(t.nanosec, 999'999'999u);
  toRosTime(-1, t);  // before the epoch: sec rounds down, nanosec stays in [0, 1e9)
  EXPECT_EQ(t.sec, -1);
  EXPECT_EQ(t.nanosec, 999'999'999u);
  for (std::int64_t t_ns : {std::int64_t{0}, std::int64_t{1}, std::int64_t{-1'000'000'001}, std::int64_t{86'400'123'456'789},
                            std::int64_t{2'000'000'000'000'000'000}}) {
    toRosTime(t_ns, t);
    EXPECT_EQ(fromRosTime(t), t_ns);
  }
}

TEST(DdsCovariance, RowMajorLayout) {
  Mat6 M;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) M(r, c) = 10.0 * r + c;  // not symmetric: the layout shows
  }
  double flat[36];
  toRowMajor(M, flat);
  EXPECT_EQ(flat[0], 0.0);
  EXPECT_EQ(flat[1], 1.0);    // (0, 1)
  EXPECT_EQ(flat[6], 10.0);   // (1, 0)
  EXPECT_EQ(flat[35], 55.0);  // (5, 5)
  EXPECT_EQ(flat[6 * 3 + 4], 34.0);
  EXPECT_EQ(fromRowMajor(flat), M);
}

// ROS PoseWithCovariance: rotation about the fixed axes of the world frame.
// The navigation state perturbs on the right (body frame); check the
// published covariance against the numerical Jacobian of that change of chart.
TEST(DdsCovariance, PoseRotationBlockIsExpressedAboutWorldAxes) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const NavigationState s = randomState(rng, 1);
    const Mat3 R = s.q_w_b.toRotationMatrix();
    const auto f = [&](const Eigen::Matrix<double, 6, 1>& d_body) -> Eigen::Matrix<double, 6, 1> {
      Eigen::Matrix<double, 6, 1> d_world;
      d_world.head<3>() = d_body.head<3>();  // position perturbation is already in world
      const Mat3 R_perturbed = R * expSo3(d_body.tail<3>());
      d_world.tail<3>() = logSo3(R_perturbed * R.transpose());
      return d_world;
    };
    const Eigen::Matrix<double, 6, 6> J = numericalJacobian<6, 6>(f);
    const Mat6 expected = J * s.pose_covariance * J.transpose();
    const Mat6 published = rosPoseCovariance(s);
    EXPECT_LE((published - expected).cwiseAbs().maxCoeff(), 1e-8) << "trial " << trial;
    EXPECT_LE((published.topLeftCorner<3, 3>() - s.pose_covariance.topLeftCorner<3, 3>()).norm(), 1e-15);
    EXPECT_LE((published - published.transpose()).cwiseAbs().maxCoeff(), 1e-15);
  }
}

TEST(DdsTwist, VelocityInBodyFrameRep105) {
  NavigationState s;
  s.q_w_b = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2.0, Vec3::UnitZ()));  // body x points to world +y
  s.v_w_b = Vec3(1.0, 0.0, 0.0);                                                // moving along world +x
  s.omega_b = Vec3(0.0, 0.0, 0.25);
  const BodyTwist twist = bodyTwist(s);
  // World +x is the body's right side, i.e. body -y.
  EXPECT_NEAR(twist.v_b.x(), 0.0, 1e-15);
  EXPECT_NEAR(twist.v_b.y(), -1.0, 1e-15);
  EXPECT_NEAR(twist.v_b.z(), 0.0, 1e-15);
  EXPECT_EQ(twist.omega_b, s.omega_b);
}

// v_b = (R Exp(dtheta))^T (v_w + dv_w), omega_b + domega: numerically
// linearized over (dv_w, domega, dtheta_b) with the state's twist covariance
// and the attitude block of the pose covariance (taken independent).
TEST(DdsTwist, CovariancePropagatesVelocityRotationAndAttitude) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    NavigationState s = randomState(rng, 1);
    s.v_w_b = testing::randomVector(rng, 3.0);
    const Mat3 R = s.q_w_b.toRotationMatrix();
    const auto g = [&](const Eigen::Matrix<double, 9, 1>& d) -> Eigen::Matrix<double, 6, 1> {
      Eigen::Matrix<double, 6, 1> out;
      out.head<3>() = (R * expSo3(d.segment<3>(6))).transpose() * (s.v_w_b + d.head<3>());
      out.tail<3>() = s.omega_b + d.segment<3>(3);
      return out;
    };
    const Eigen::Matrix<double, 6, 9> J = numericalJacobian<6, 9>(g);
    Eigen::Matrix<double, 9, 9> P = Eigen::Matrix<double, 9, 9>::Zero();
    P.topLeftCorner<6, 6>() = s.twist_covariance;
    P.bottomRightCorner<3, 3>() = s.pose_covariance.bottomRightCorner<3, 3>();
    const Mat6 expected = J * P * J.transpose();
    const BodyTwist twist = bodyTwist(s);
    EXPECT_LE((twist.covariance - expected).cwiseAbs().maxCoeff(), 1e-7) << "trial " << trial;
    EXPECT_LE((twist.v_b - R.transpose() * s.v_w_b).norm(), 1e-12);
    EXPECT_LE((twist.covariance - twist.covariance.transpose()).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(DdsTwist, AtRestOnlyRotatesTheVelocityCovariance) {
  std::mt19937 rng(3);
  NavigationState s = randomState(rng, 1);
  s.v_w_b.setZero();
  const Mat3 R = s.q_w_b.toRotationMatrix();
  const BodyTwist twist = bodyTwist(s);
  EXPECT_LE((twist.covariance.topLeftCorner<3, 3>() - R.transpose() * s.twist_covariance.topLeftCorner<3, 3>() * R)
                .cwiseAbs()
                .maxCoeff(),
            1e-14);
  // Rotating an isotropic velocity covariance changes nothing.
  s.twist_covariance.topLeftCorner<3, 3>() = 0.04 * Mat3::Identity();
  s.twist_covariance.topRightCorner<3, 3>().setZero();
  s.twist_covariance.bottomLeftCorner<3, 3>().setZero();
  EXPECT_LE((bodyTwist(s).covariance.topLeftCorner<3, 3>() - 0.04 * Mat3::Identity()).cwiseAbs().maxCoeff(), 1e-15);
}

TEST(DdsFill, OdometryFieldsExact) {
  std::mt19937 rng(5);
  NavigationState s = randomState(rng, 1'700'000'123'456'789);
  s.q_w_b.coeffs() *= 2.0;  // not normalized: the message carries the unit quaternion
  nav_msgs_msg_dds__Odometry_ msg{};
  fillOdometry(s, msg);
  EXPECT_EQ(msg.header.stamp.sec, 1'700'000);
  EXPECT_EQ(msg.header.stamp.nanosec, 123'456'789u);
  EXPECT_EQ(msg.header.frame_id, nullptr);  // strings are the publisher's business
  EXPECT_EQ(msg.child_frame_id, nullptr);
  EXPECT_EQ(msg.pose.pose.position.x, s.p_w_b.x());
  EXPECT_EQ(msg.pose.pose.position.y, s.p_w_b.y());
  EXPECT_EQ(msg.pose.pose.position.z, s.p_w_b.z());
  const Eigen::Quaterniond q = s.q_w_b.normalized();
  EXPECT_EQ(msg.pose.pose.orientation.x, q.x());
  EXPECT_EQ(msg.pose.pose.orientation.y, q.y());
  EXPECT_EQ(msg.pose.pose.orientation.z, q.z());
  EXPECT_EQ(msg.pose.pose.orientation.w, q.w());
  EXPECT_EQ(fromRowMajor(msg.pose.covariance), rosPoseCovariance(s));
  const BodyTwist twist = bodyTwist(s);
  EXPECT_EQ(msg.twist.twist.linear.x, twist.v_b.x());
  EXPECT_EQ(msg.twist.twist.linear.y, twist.v_b.y());
  EXPECT_EQ(msg.twist.twist.linear.z, twist.v_b.z());
  EXPECT_EQ(msg.twist.twist.angular.x, s.omega_b.x());
  EXPECT_EQ(msg.twist.twist.angular.y, s.omega_b.y());
  EXPECT_EQ(msg.twist.twist.angular.z, s.omega_b.z());
  EXPECT_EQ(fromRowMajor(msg.twist.covariance), twist.covariance);
  // Row-major: element (0, 3) is cov(x, rot x) and (3, 0) its transpose partner.
  EXPECT_EQ(msg.pose.covariance[3], rosPoseCovariance(s)(0, 3));
  EXPECT_EQ(msg.pose.covariance[1 * 6 + 5], rosPoseCovariance(s)(1, 5));

  const OdometryMessage back = toOdometryMessage(msg);
  EXPECT_EQ(back.stamp_ns, s.t_ns);
  EXPECT_EQ(back.p_w_b, s.p_w_b);
  EXPECT_EQ(back.q_w_b.coeffs(), q.coeffs());
  EXPECT_EQ(back.v_b, twist.v_b);
  EXPECT_EQ(back.twist_covariance, twist.covariance);
  EXPECT_TRUE(back.frame_id.empty());
}

TEST(DdsFill, PoseFieldsExact) {
  std::mt19937 rng(6);
  const NavigationState s = randomState(rng, 42'000'000'001);
  geometry_msgs_msg_dds__PoseWithCovarianceStamped_ msg{};
  fillPose(s, msg);
  EXPECT_EQ(msg.header.stamp.sec, 42);
  EXPECT_EQ(msg.header.stamp.nanosec, 1u);
  const PoseMessage back = toPoseMessage(msg);
  EXPECT_EQ(back.stamp_ns, s.t_ns);
  EXPECT_EQ(back.p_w_b, s.p_w_b);
  EXPECT_EQ(back.q_w_b.coeffs(), s.q_w_b.normalized().coeffs());
  EXPECT_EQ(back.covariance, rosPoseCovariance(s));
}

TEST(DdsFill, StatusRoundTrip) {
  const ServiceStatus s = testing::sampleStatus(5'000'000'123);
  rilo_msg_dds__Status_ msg{};
  fillStatus(s, msg);
  char name[] = "degraded";
  char fault[] = "dwm3000 /dev/spidev0.0: RX timeout";
  char reason[] = "no ranging for 12.4 s (IMU only)";
  msg.state_name = name;
  msg.last_fault = fault;
  msg.reason = reason;
  EXPECT_EQ(msg.state, 2u);
  EXPECT_EQ(msg.header.stamp.sec, 5);
  EXPECT_EQ(msg.header.stamp.nanosec, 123u);
  const StatusMessage back = toStatusMessage(msg);
  EXPECT_EQ(back.state_name, "degraded");
  EXPECT_EQ(back.status.t_ns, s.t_ns);
  EXPECT_EQ(back.status.state, s.state);
  EXPECT_EQ(back.status.imu_samples, s.imu_samples);
  EXPECT_EQ(back.status.range_samples, s.range_samples);
  EXPECT_EQ(back.status.queue_overflows, s.queue_overflows);
  EXPECT_EQ(back.status.late_updates, s.late_updates);
  EXPECT_EQ(back.status.sensor_faults, s.sensor_faults);
  EXPECT_EQ(back.status.sensor_silences, s.sensor_silences);
  EXPECT_EQ(back.status.reinitializations, s.reinitializations);
  EXPECT_EQ(back.status.rejected_ranges, s.rejected_ranges);
  EXPECT_EQ(back.status.deep_nlos_tdoa_rows, s.deep_nlos_tdoa_rows);
  EXPECT_EQ(back.status.tdoa_samples, s.tdoa_samples);
  EXPECT_EQ(back.status.ultrasonic_samples, s.ultrasonic_samples);
  EXPECT_EQ(back.status.published_odometry, s.published_odometry);
  EXPECT_EQ(back.status.non_finite_samples, s.non_finite_samples);
  EXPECT_EQ(back.status.duplicate_samples, s.duplicate_samples);
  EXPECT_EQ(back.status.out_of_order_samples, s.out_of_order_samples);
  EXPECT_EQ(back.status.imu_gaps, s.imu_gaps);
  EXPECT_EQ(back.status.ranging_gaps, s.ranging_gaps);
  EXPECT_EQ(back.status.out_of_bounds_samples, s.out_of_bounds_samples);
  EXPECT_EQ(back.status.beyond_full_scale_samples, s.beyond_full_scale_samples);
  EXPECT_EQ(back.status.far_future_samples, s.far_future_samples);
  EXPECT_EQ(back.status.time_jumps, s.time_jumps);
  EXPECT_EQ(back.status.last_update_ms, s.last_update_ms);
  EXPECT_EQ(back.status.mean_update_ms, s.mean_update_ms);
  EXPECT_EQ(back.status.max_update_ms, s.max_update_ms);
  EXPECT_EQ(back.status.p99_update_ms, s.p99_update_ms);
  EXPECT_EQ(back.status.estimator_queue_high_water, s.estimator_queue_high_water);
  EXPECT_EQ(back.status.publisher_queue_high_water, s.publisher_queue_high_water);
  EXPECT_EQ(back.status.last_cliques_reeliminated, s.last_cliques_reeliminated);
  EXPECT_EQ(back.status.last_relinearized, s.last_relinearized);
  EXPECT_EQ(back.status.last_lambda, s.last_lambda);
  EXPECT_EQ(back.status.odometry_latency_ms, s.odometry_latency_ms);
  EXPECT_EQ(back.status.pose_latency_ms, s.pose_latency_ms);
  EXPECT_STREQ(back.status.last_fault.data(), s.last_fault.data());
  EXPECT_STREQ(back.status.reason.data(), s.reason.data());
}

TEST(DdsFill, StatusFaultLongerThanServiceStatusIsTruncated) {
  rilo_msg_dds__Status_ msg{};
  std::string long_fault(300, 'x');
  msg.last_fault = long_fault.data();
  const StatusMessage back = toStatusMessage(msg);
  EXPECT_EQ(std::strlen(back.status.last_fault.data()), back.status.last_fault.size() - 1);
  EXPECT_TRUE(back.state_name.empty());  // null string reads as empty
  EXPECT_STREQ(back.status.reason.data(), "");
}

TEST(DdsFill, TrackingStateNames) {
  EXPECT_STREQ(trackingStateName(TrackingState::kInitializing), "initializing");
  EXPECT_STREQ(trackingStateName(TrackingState::kTracking), "tracking");
  EXPECT_STREQ(trackingStateName(TrackingState::kDegraded), "degraded");
  EXPECT_STREQ(trackingStateName(TrackingState::kLost), "lost");
}

}  // namespace
}  // namespace rilo::dds
