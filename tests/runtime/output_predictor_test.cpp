#include "runtime/output_predictor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <vector>

#include "math/so3.h"
#include "runtime/support/analytic_motion.h"

namespace rilo {
namespace {

using testing::idealImuAt;
using testing::motionAt;
using testing::toSeconds;
using testing::truthAt;

constexpr std::int64_t kPeriodNs = 5'000'000;  // 200 Hz IMU
constexpr std::int64_t kT0Ns = 2'000'000'000;  // samples at kT0Ns + k kPeriodNs

std::int64_t sampleTime(int k) { return kT0Ns + k * kPeriodNs; }

double rotationError(const Quat& a, const Quat& b) {
  return so3::log(a.toRotationMatrix().transpose() * b.toRotationMatrix()).norm();
}

void expectIdentical(const NavigationState& a, const NavigationState& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.q_w_b.coeffs(), b.q_w_b.coeffs());
  EXPECT_EQ(a.p_w_b, b.p_w_b);
  EXPECT_EQ(a.v_w_b, b.v_w_b);
  EXPECT_EQ(a.omega_b, b.omega_b);
  EXPECT_EQ(a.pose_covariance, b.pose_covariance);
  EXPECT_EQ(a.twist_covariance, b.twist_covariance);
  EXPECT_EQ(a.valid, b.valid);
}

TEST(AnalyticMotion, BodyRateMatchesRotationDerivative) {
  // The test fixture itself: omega_b against a central difference of R(t).
  for (double t : {0.0, 1.3, 7.9}) {
    const double h = 1e-6;
    const Mat3 dR = motionAt(t - h).R_w_b.transpose() * motionAt(t + h).R_w_b;
    const Vec3 omega_fd = so3::log(dR) / (2 * h);
    EXPECT_LE((omega_fd - motionAt(t).omega_b).norm(), 1e-6) << "t " << t;
    const Vec3 v_fd = (motionAt(t + h).p_w - motionAt(t - h).p_w) / (2 * h);
    EXPECT_LE((v_fd - motionAt(t).v_w).norm(), 1e-6);
    const Vec3 a_fd = (motionAt(t + h).v_w - motionAt(t - h).v_w) / (2 * h);
    EXPECT_LE((a_fd - motionAt(t).a_w).norm(), 1e-6);
  }
}

TEST(OutputPredictor, InvalidUntilFirstSmoothedState) {
  OutputPredictor pred;
  for (int k = 0; k < 10; ++k) EXPECT_FALSE(pred.onImu(idealImuAt(sampleTime(k))).valid);
  EXPECT_EQ(pred.bufferedSamples(), 10u);
}

// Ideal IMU with biases, smoothed state at a time between two samples:
// the output follows the true motion to well below a millimetre over 1 s.
TEST(OutputPredictor, TracksTruthOverOneSecond) {
  const Vec3 b_a(0.05, -0.03, 0.08), b_g(0.002, -0.001, 0.003);
  OutputPredictor pred;
  for (int k = 0; k <= 20; ++k) pred.onImu(idealImuAt(sampleTime(k), 9.81, b_a, b_g));
  const std::int64_t t_smoothed = sampleTime(17) + 1'300'000;  // between samples 17 and 18
  const NavigationState& after = pred.onSmoothed(truthAt(t_smoothed, b_a, b_g));
  EXPECT_EQ(after.t_ns, sampleTime(20));

  double max_p = 0, max_v = 0, max_r = 0;
  for (int k = 21; k <= 20 + 200; ++k) {
    const std::int64_t t = sampleTime(k);
    const NavigationState& out = pred.onImu(idealImuAt(t, 9.81, b_a, b_g));
    ASSERT_TRUE(out.valid);
    ASSERT_EQ(out.t_ns, t);
    const NavigationState truth = truthAt(t);
    max_p = std::max(max_p, (out.p_w_b - truth.p_w_b).norm());
    max_v = std::max(max_v, (out.v_w_b - truth.v_w_b).norm());
    max_r = std::max(max_r, rotationError(out.q_w_b, truth.q_w_b));
    EXPECT_LE((out.omega_b - truth.omega_b).norm(), 1e-12);
  }
  EXPECT_LT(max_p, 1e-3);
  EXPECT_LT(max_v, 1e-3);
  EXPECT_LT(max_r, 1e-4);
  // Second-order integration: far below the requirement.
  EXPECT_LT(max_p, 1e-4);
}

// The output after a correction equals, bit for bit, what a predictor that
// started from the corrected state would have produced from the same samples.
TEST(OutputPredictor, SmoothedCorrectionJumpsExactlyToReintegratedValue) {
  constexpr int kM = 40, kN = 100;  // smoothed state at sample kM, handed over at sample kN
  OutputPredictor a;
  a.onSmoothed(truthAt(sampleTime(0)));
  for (int k = 0; k <= kN; ++k) a.onImu(idealImuAt(sampleTime(k)));
  // Output re-integrated from the uncorrected state at the same time, for comparison.
  const NavigationState before = a.onSmoothed(truthAt(sampleTime(kM)));

  NavigationState corrected = truthAt(sampleTime(kM));
  const Vec3 dp(0.3, -0.2, 0.1);
  corrected.p_w_b += dp;
  corrected.pose_covariance *= 4.0;
  const NavigationState after = a.onSmoothed(corrected);

  OutputPredictor b;
  for (int k = 0; k <= kM; ++k) b.onImu(idealImuAt(sampleTime(k)));
  b.onSmoothed(corrected);
  for (int k = kM + 1; k <= kN; ++k) b.onImu(idealImuAt(sampleTime(k)));
  expectIdentical(after, b.state());

  // A pure position offset moves the whole re-integrated output by exactly it.
  EXPECT_EQ(after.t_ns, sampleTime(kN));
  EXPECT_LE((after.p_w_b - before.p_w_b - dp).norm(), 1e-12);
  EXPECT_EQ(after.v_w_b, before.v_w_b);
  EXPECT_EQ(after.q_w_b.coeffs(), before.q_w_b.coeffs());

  // Both continue identically.
  for (int k = kN + 1; k <= kN + 20; ++k) {
    const ImuSample s = idealImuAt(sampleTime(k));
    expectIdentical(a.onImu(s), b.onImu(s));
  }
}

TEST(OutputPredictor, VelocityCorrectionPropagatesThroughReintegration) {
  OutputPredictor pred;
  for (int k = 0; k <= 60; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  NavigationState s = truthAt(sampleTime(20));
  pred.onSmoothed(s);
  const NavigationState base = pred.state();
  const Vec3 dv(0.1, 0.0, -0.05);
  s.v_w_b += dv;
  const NavigationState moved = pred.onSmoothed(s);
  const double dt = toSeconds(sampleTime(60) - sampleTime(20));
  EXPECT_LE((moved.p_w_b - base.p_w_b - dv * dt).norm(), 1e-9);
  EXPECT_LE((moved.v_w_b - base.v_w_b - dv).norm(), 1e-9);
}

TEST(OutputPredictor, CovarianceGrowsWithTimeSinceSmoothedState) {
  OutputPredictorParams params;
  params.position_random_walk = 0.1;
  params.rotation_random_walk = 0.01;
  params.velocity_random_walk = 0.2;
  OutputPredictor pred(params);
  NavigationState s = truthAt(sampleTime(0));
  s.pose_covariance = Mat6::Identity() * 1e-4;
  s.twist_covariance = Mat6::Identity() * 4e-3;
  s.twist_covariance(1, 0) = s.twist_covariance(0, 1) = 1e-3;
  pred.onSmoothed(s);
  EXPECT_EQ(pred.state().pose_covariance, s.pose_covariance);  // no time elapsed
  for (int k = 1; k <= 100; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  const double dt = toSeconds(sampleTime(100) - sampleTime(0));
  const NavigationState& out = pred.state();
  Mat6 expected_pose = s.pose_covariance;
  expected_pose.topLeftCorner<3, 3>() += dt * dt * s.twist_covariance.topLeftCorner<3, 3>();
  expected_pose.topLeftCorner<3, 3>().diagonal().array() += 0.1 * 0.1 * dt;
  expected_pose.bottomRightCorner<3, 3>().diagonal().array() += 0.01 * 0.01 * dt;
  Mat6 expected_twist = s.twist_covariance;
  expected_twist.topLeftCorner<3, 3>().diagonal().array() += 0.2 * 0.2 * dt;
  EXPECT_LE((out.pose_covariance - expected_pose).norm(), 1e-15);
  EXPECT_LE((out.twist_covariance - expected_twist).norm(), 1e-15);
  const Mat3 angular_out = out.twist_covariance.bottomRightCorner<3, 3>();
  const Mat3 angular_smoothed = s.twist_covariance.bottomRightCorner<3, 3>();
  EXPECT_EQ(angular_out, angular_smoothed);
}

// The published body rate is one gyro sample less the bias (issue 39: its
// covariance used to be the identity): per axis, the sample's white noise
// density^2 / dt plus the bias variance, no correlation with the velocity.
TEST(OutputPredictor, BodyRateCovarianceIsTheGyroSamplesNoiseAndTheBiasUncertainty) {
  OutputPredictorParams params;
  params.gyro_noise_density = 2.8e-4;
  params.gyro_bias_sigma = 0.01;
  OutputPredictor pred(params);
  NavigationState s = truthAt(sampleTime(0));
  s.twist_covariance = Mat6::Identity();
  s.twist_covariance(4, 1) = s.twist_covariance(1, 4) = 0.5;
  pred.onSmoothed(s);
  for (int k = 1; k <= 10; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  const double dt = toSeconds(sampleTime(10) - sampleTime(9));
  const Mat6& P = pred.state().twist_covariance;
  const double expected = 2.8e-4 * 2.8e-4 / dt + 0.01 * 0.01;
  EXPECT_NEAR(P(3, 3), expected, 1e-15);
  EXPECT_NEAR(P(5, 5), expected, 1e-15);
  EXPECT_EQ(P(4, 3), 0.0);
  const Mat3 cross = P.topRightCorner<3, 3>();
  const Mat3 cross_t = P.bottomLeftCorner<3, 3>();
  EXPECT_EQ(cross.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(cross_t.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_LT(std::sqrt(P(3, 3)), 0.02) << "rad/s: a gyro's, not 1 rad/s";

  // A smoothed state 1 us before a sample (states sit at range times, off
  // the IMU grid): the first step covers 1 us, the noise is still a whole
  // sample interval's.
  OutputPredictor late(params);
  for (int k = 0; k <= 5; ++k) late.onImu(idealImuAt(sampleTime(k)));
  NavigationState s2 = truthAt(sampleTime(6) - 1000);
  late.onSmoothed(s2);
  late.onImu(idealImuAt(sampleTime(6)));
  EXPECT_EQ(late.state().t_ns, sampleTime(6));
  EXPECT_NEAR(late.state().twist_covariance(3, 3), expected, 1e-15);
}

// Full ring: the oldest sample is overwritten and counted. A smoothed state
// older than everything buffered re-integrates what is left, holding the
// oldest buffered sample over the gap, and is counted as truncated.
TEST(OutputPredictor, RingOverflowDropsOldestAndTruncatesReintegration) {
  OutputPredictorParams params;
  params.imu_buffer_capacity = 8;
  OutputPredictor pred(params);
  for (int k = 0; k < 20; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  EXPECT_EQ(pred.bufferedSamples(), 8u);
  EXPECT_EQ(pred.droppedSamples(), 12u);

  const NavigationState old_state = truthAt(sampleTime(5));
  const NavigationState truncated = pred.onSmoothed(old_state);
  EXPECT_EQ(pred.truncatedReintegrations(), 1u);
  EXPECT_EQ(truncated.t_ns, sampleTime(19));
  // Reference: the same state, then only the samples still buffered (12..19).
  OutputPredictor ref(params);
  ref.onSmoothed(old_state);
  for (int k = 12; k < 20; ++k) ref.onImu(idealImuAt(sampleTime(k)));
  expectIdentical(truncated, ref.state());

  // A state inside the buffered span is re-integrated exactly, not truncated.
  const NavigationState& exact = pred.onSmoothed(truthAt(sampleTime(14)));
  EXPECT_EQ(pred.truncatedReintegrations(), 1u);
  EXPECT_LT((exact.p_w_b - truthAt(sampleTime(19)).p_w_b).norm(), 1e-6);
}

TEST(OutputPredictor, RejectsSamplesThatDoNotAdvanceTime) {
  OutputPredictor pred;
  pred.onSmoothed(truthAt(sampleTime(0)));
  pred.onImu(idealImuAt(sampleTime(1)));
  const NavigationState before = pred.state();
  pred.onImu(idealImuAt(sampleTime(1)));     // same time
  pred.onImu(idealImuAt(sampleTime(0) + 1));  // older
  EXPECT_EQ(pred.rejectedSamples(), 2u);
  EXPECT_EQ(pred.bufferedSamples(), 1u);
  expectIdentical(pred.state(), before);
}

TEST(OutputPredictor, InvalidSmoothedStateStopsOutput) {
  OutputPredictor pred;
  pred.onSmoothed(truthAt(sampleTime(0)));
  EXPECT_TRUE(pred.onImu(idealImuAt(sampleTime(1))).valid);
  NavigationState lost = truthAt(sampleTime(1));
  lost.valid = false;
  EXPECT_FALSE(pred.onSmoothed(lost).valid);
  EXPECT_FALSE(pred.onImu(idealImuAt(sampleTime(2))).valid);
  EXPECT_TRUE(pred.onSmoothed(truthAt(sampleTime(2))).valid);
  EXPECT_TRUE(pred.onImu(idealImuAt(sampleTime(3))).valid);
}

// A smoothed state newer than the newest sample: the output holds it until
// the IMU catches up, then integrates from it (interpolating the measurement
// at its time).
TEST(OutputPredictor, SmoothedStateAheadOfImuWaitsForSamples) {
  OutputPredictor pred;
  for (int k = 0; k <= 10; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  const std::int64_t t_s = sampleTime(12) + 2'000'000;
  EXPECT_EQ(pred.onSmoothed(truthAt(t_s)).t_ns, t_s);
  EXPECT_EQ(pred.onImu(idealImuAt(sampleTime(11))).t_ns, t_s);
  EXPECT_EQ(pred.onImu(idealImuAt(sampleTime(12))).t_ns, t_s);
  for (int k = 13; k <= 60; ++k) {
    const NavigationState& out = pred.onImu(idealImuAt(sampleTime(k)));
    ASSERT_EQ(out.t_ns, sampleTime(k));
    EXPECT_LT((out.p_w_b - truthAt(sampleTime(k)).p_w_b).norm(), 1e-5);
  }
}

TEST(OutputPredictor, OutputQuaternionIsNormalized) {
  OutputPredictor pred;
  NavigationState s = truthAt(sampleTime(0));
  s.q_w_b.coeffs() *= 3.0;  // the estimator may hand over an unnormalized quaternion
  EXPECT_NEAR(pred.onSmoothed(s).q_w_b.norm(), 1.0, 1e-15);
  for (int k = 1; k < 2000; ++k) pred.onImu(idealImuAt(sampleTime(k)));
  EXPECT_NEAR(pred.state().q_w_b.norm(), 1.0, 1e-15);
}

TEST(OutputPredictorParams, RejectsBadValuesNamingTheField) {
  const auto message = [](const OutputPredictorParams& p) {
    try {
      OutputPredictor pred(p);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  OutputPredictorParams p;
  p.imu_buffer_capacity = 1;
  EXPECT_NE(message(p).find("imu_buffer_capacity"), std::string::npos);
  p = {};
  p.gravity_m_s2 = std::nan("");
  EXPECT_NE(message(p).find("gravity_m_s2"), std::string::npos);
  p = {};
  p.velocity_random_walk = -1.0;
  EXPECT_NE(message(p).find("velocity_random_walk"), std::string::npos);
  p = {};
  p.gyro_noise_density = -1.0;
  EXPECT_NE(message(p).find("gyro_noise_density"), std::string::npos);
  p = {};
  p.gyro_bias_sigma = std::nan("");
  EXPECT_NE(message(p).find("gyro_bias_sigma"), std::string::npos);
  EXPECT_NO_THROW(OutputPredictor{OutputPredictorParams{}});
}

}  // namespace
}  // namespace rilo
