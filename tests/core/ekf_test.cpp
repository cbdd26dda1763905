// Error-state EKF: charts, Jacobians, update algebra, input handling.
// Closed-loop tracking (convergence, NEES, gating, TDoA, ultrasonic) is in
// ekf_tracking_test.cpp; the no-allocation check in ekf_alloc_test.cpp.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>

#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/ekf/ekf_propagation.h"
#include "estimation/ekf/error_state_ekf.h"
#include "estimation/noise/asymmetric_loss.h"
#include "estimation/noise/huber_loss.h"
#include "sim/trajectory.h"
#include "support/expect_throws_naming.h"
#include "support/random_states.h"

namespace rilo {
namespace {

using rilo::testing::expectThrowsNaming;

using testing::randomRotation;
using testing::randomVec;
using namespace ekf_index;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

EkfState randomState(std::mt19937& rng) {
  EkfState x;
  x.R_w_b = randomRotation(rng);
  x.p_w_b = randomVec(rng, 3.0);
  x.v_w = randomVec(rng, 1.0);
  x.bias = ImuBias(randomVec(rng, 0.1), randomVec(rng, 0.01));
  return x;
}

Mat15 diagonalCovariance(double s_theta, double s_p, double s_v, double s_ba, double s_bg) {
  Vec15 s;
  s << Vec3::Constant(s_theta), Vec3::Constant(s_p), Vec3::Constant(s_v), Vec3::Constant(s_ba),
      Vec3::Constant(s_bg);
  return s.cwiseAbs2().asDiagonal();
}

ImuSample sampleAt(std::int64_t t_ns, const Vec3& gyro, const Vec3& accel) {
  ImuSample s;
  s.t_ns = t_ns;
  s.gyro_rad_s = gyro;
  s.accel_m_s2 = accel;
  return s;
}

// Central differences of h(x (+) dx) over all 15 error coordinates.
template <int M, typename Fn>
Eigen::Matrix<double, M, 15> numericalH(const EkfState& x, Fn h, double step = 1e-6) {
  Eigen::Matrix<double, M, 15> J;
  for (int i = 0; i < 15; ++i) {
    Vec15 d = Vec15::Zero();
    d(i) = step;
    J.col(i) = (h(x.retract(d)) - h(x.retract(-d))) / (2.0 * step);
  }
  return J;
}

template <int M>
Eigen::Matrix<double, M, 15> fullH(const EkfPrediction<M>& p) {
  Eigen::Matrix<double, M, 15> H = Eigen::Matrix<double, M, 15>::Zero();
  H.template leftCols<6>() = p.H;
  return H;
}

TEST(EkfState, LocalIsInverseOfRetract) {
  std::mt19937 rng(11);
  for (int i = 0; i < 20; ++i) {
    const EkfState x = randomState(rng);
    Vec15 dx;
    for (int k = 0; k < 15; ++k) dx(k) = std::normal_distribution<double>(0.0, 0.5)(rng);
    EXPECT_LE((x.local(x.retract(dx)) - dx).norm(), 1e-10);
  }
}

TEST(EkfMeasurementModels, JacobiansMatchFiniteDifferencesAtRandomStates) {
  std::mt19937 rng(12);
  for (int i = 0; i < 50; ++i) {
    const EkfState x = randomState(rng);
    const Vec3 A = randomVec(rng, 4.0), B = randomVec(rng, 4.0);
    const Vec3 lever = randomVec(rng, 0.3);
    const auto range = [&](const EkfState& s) { return predictRange(s, A, lever).h; };
    const auto tdoa = [&](const EkfState& s) { return predictTdoa(s, A, B, lever).h; };
    const auto us = [&](const EkfState& s) { return predictUltrasonic(s, A, lever).h; };
    EXPECT_LE((numericalH<1>(x, range) - fullH(predictRange(x, A, lever))).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LE((numericalH<1>(x, tdoa) - fullH(predictTdoa(x, A, B, lever))).cwiseAbs().maxCoeff(), 1e-7);
    EXPECT_LE((numericalH<2>(x, us) - fullH(predictUltrasonic(x, A, lever))).cwiseAbs().maxCoeff(), 1e-7);
    // Values agree with the factors' models.
    const Vec3 p_tag = x.R_w_b * lever + x.p_w_b;
    EXPECT_NEAR(predictRange(x, A, lever).h(0), (p_tag - A).norm(), 1e-12);
    EXPECT_NEAR(predictTdoa(x, A, B, lever).h(0), (p_tag - B).norm() - (p_tag - A).norm(), 1e-12);
    EXPECT_NEAR(predictUltrasonic(x, A, lever).h(1), p_tag.z() - A.z(), 1e-12);
  }
}

TEST(EkfMeasurementModels, JacobiansNearSingularConfigurations) {
  std::mt19937 rng(13);
  for (int i = 0; i < 20; ++i) {
    const EkfState x = randomState(rng);
    const Vec3 lever = randomVec(rng, 0.3);
    const Vec3 p_tag = x.R_w_b * lever + x.p_w_b;
    // Tag 1 mm from the anchor (FD step 1e-7 stays well inside).
    const Vec3 A = p_tag + 1e-3 * randomVec(rng, 1.0).normalized();
    const Vec3 B = p_tag + randomVec(rng, 3.0);
    const auto range = [&](const EkfState& s) { return predictRange(s, A, lever).h; };
    const auto tdoa = [&](const EkfState& s) { return predictTdoa(s, A, B, lever).h; };
    EXPECT_LE((numericalH<1>(x, range, 1e-7) - fullH(predictRange(x, A, lever))).cwiseAbs().maxCoeff(), 1e-5);
    EXPECT_LE((numericalH<1>(x, tdoa, 1e-7) - fullH(predictTdoa(x, A, B, lever))).cwiseAbs().maxCoeff(), 1e-5);
    // Exactly on the anchor: finite, unit direction (0, 0, -1) convention.
    const EkfPrediction<1> on = predictRange(x, p_tag, lever);
    EXPECT_TRUE(on.H.allFinite());
    EXPECT_NEAR(on.h(0), 0.0, 1e-12);
    EXPECT_LE((on.H.tail<3>() - Vec3(0, 0, -1).transpose()).norm(), 1e-12);
  }
  // Tag on the vertical through the anchor: the elevation row equals the range row up to sign.
  EkfState x;
  const EkfPrediction<2> us = predictUltrasonic(x, Vec3(0, 0, 2.5), Vec3::Zero());
  EXPECT_LE((us.H.row(0) + us.H.row(1)).norm(), 1e-12);
}

TEST(EkfPropagation, TransitionMatchesFiniteDifferences) {
  std::mt19937 rng(14);
  const Vec3 g_w(0, 0, -9.81);
  for (int i = 0; i < 30; ++i) {
    const EkfState x = randomState(rng);
    const ImuInterval m{randomVec(rng, 1.0), randomVec(rng, 5.0) + Vec3(0, 0, 9.81), randomVec(rng, 1.0),
                        randomVec(rng, 5.0) + Vec3(0, 0, 9.81), i % 3 == 0 ? 0.05 : 0.005};
    Vec6 phi = Vec6::Ones();
    if (i % 2 == 1) phi.setConstant(std::exp(-m.dt_s / 50.0));
    Mat15 F;
    const EkfState x1 = integrateImuMidpoint(x, m, g_w, phi, &F);
    Mat15 F_num;
    const double h = 1e-6;
    for (int k = 0; k < 15; ++k) {
      Vec15 d = Vec15::Zero();
      d(k) = h;
      const EkfState xp = integrateImuMidpoint(x.retract(d), m, g_w, phi, nullptr);
      const EkfState xm = integrateImuMidpoint(x.retract(-d), m, g_w, phi, nullptr);
      F_num.col(k) = (x1.local(xp) - x1.local(xm)) / (2.0 * h);
    }
    EXPECT_LE((F_num - F).cwiseAbs().maxCoeff(), 1e-7) << "case " << i;
  }
}

TEST(EkfPropagation, EulerWhenBothEndsEqualHoldsTheSample) {
  // Constant specific force opposing gravity and a constant rate: closed form.
  EkfState x;
  const Vec3 w(0.0, 0.0, 0.4);
  const ImuInterval m{w, Vec3(0, 0, 9.81), w, Vec3(0, 0, 9.81), 0.01};
  const EkfState x1 = integrateImuMidpoint(x, m, Vec3(0, 0, -9.81), Vec6::Ones(), nullptr);
  EXPECT_LE((x1.R_w_b - so3::exp(w * 0.01)).norm(), 1e-15);
  EXPECT_LE(x1.p_w_b.norm(), 1e-15);
  EXPECT_LE(x1.v_w.norm(), 1e-15);
}

struct IdealRunErrors {
  double theta_rad = 0.0, p_m = 0.0, v_m_s = 0.0;  ///< maxima over the run
};

// Ideal IMU of the LissajousWalk at rate_hz for 10 s from the true state, no updates.
IdealRunErrors runIdealImu(int rate_hz, ErrorStateEkf& ekf) {
  const sim::LissajousWalk walk;
  const sim::KinematicState s0 = walk.at(0.0);
  ekf.initialize(0, EkfState(s0.T_w_b, s0.v_w, ImuBias()), diagonalCovariance(0.01, 0.01, 0.01, 0.01, 0.001));
  const std::int64_t dt_ns = 1'000'000'000 / rate_hz;
  IdealRunErrors e;
  for (std::int64_t k = 0; k <= 10 * rate_hz; ++k) {
    const sim::KinematicState s = walk.at(1e-9 * static_cast<double>(k * dt_ns));
    const sim::ImuReading imu = sim::idealImu(s, ekf.params().imu.gravity_m_s2);
    const PropagateStatus st = ekf.propagate(sampleAt(k * dt_ns, imu.gyro, imu.accel));
    EXPECT_EQ(st, k == 0 ? PropagateStatus::kFirstSample : PropagateStatus::kPropagated);
    const Vec15 err = ekf.state().local(EkfState(s.T_w_b, s.v_w, ImuBias()));
    e.theta_rad = std::max(e.theta_rad, err.segment<3>(kTheta).norm());
    e.p_m = std::max(e.p_m, err.segment<3>(kPos).norm());
    e.v_m_s = std::max(e.v_m_s, err.segment<3>(kVel).norm());
  }
  return e;
}

TEST(ErrorStateEkf, IdealImuTracksLissajousWalkForTenSeconds) {
  ErrorStateEkf ekf;
  const IdealRunErrors e200 = runIdealImu(200, ekf);
  EXPECT_EQ(ekf.t_ns(), 10'000'000'000);
  EXPECT_EQ(ekf.counters().imu_propagated, 2000u);
  // Midpoint rule: ~8e-7 rad, 8e-5 m, 2e-5 m/s at 200 Hz (limits with margin).
  EXPECT_LT(e200.theta_rad, 5e-6);
  EXPECT_LT(e200.p_m, 5e-4);
  EXPECT_LT(e200.v_m_s, 1e-4);
  const Mat15& P = ekf.covariance();
  EXPECT_EQ((P - P.transpose()).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_EQ(Eigen::LLT<Mat15>(P).info(), Eigen::Success);
  // Second order: halving dt divides the error by ~4.
  ErrorStateEkf ekf100;
  const IdealRunErrors e100 = runIdealImu(100, ekf100);
  EXPECT_GT(e100.p_m / e200.p_m, 3.5);
  EXPECT_GT(e100.theta_rad / e200.theta_rad, 3.5);
}

TEST(ErrorStateEkf, IrregularSampleTimesStillTrack) {
  const sim::LissajousWalk walk;
  ErrorStateEkf ekf;
  const sim::KinematicState s0 = walk.at(0.0);
  ekf.initialize(0, EkfState(s0.T_w_b, s0.v_w, ImuBias()), diagonalCovariance(0.01, 0.01, 0.01, 0.01, 0.001));
  std::mt19937 rng(15);
  std::uniform_int_distribution<std::int64_t> jitter(1'000'000, 9'000'000);  // 1..9 ms
  std::int64_t t_ns = 0;
  while (t_ns < 10'000'000'000) {
    const sim::KinematicState s = walk.at(1e-9 * static_cast<double>(t_ns));
    const sim::ImuReading imu = sim::idealImu(s);
    ekf.propagate(sampleAt(t_ns, imu.gyro, imu.accel));
    t_ns += jitter(rng);
  }
  const sim::KinematicState s = walk.at(1e-9 * static_cast<double>(ekf.t_ns()));
  const Vec15 err = ekf.state().local(EkfState(s.T_w_b, s.v_w, ImuBias()));
  EXPECT_LT(err.segment<3>(kTheta).norm(), 5e-6);  // ~7e-7 rad
  EXPECT_LT(err.segment<3>(kPos).norm(), 1e-3);     // ~1.2e-4 m
}

TEST(ErrorStateEkf, PropagateReportsBadTimingAndLeavesTheStateAlone) {
  ErrorStateEkf ekf;
  EXPECT_THROW(ekf.propagate(sampleAt(0, Vec3::Zero(), Vec3::Zero())), std::logic_error);
  const std::int64_t t0 = 1'000'000'000;
  ekf.initialize(t0, EkfState(), Mat15::Identity() * 1e-2);
  const Vec3 f(0, 0, 9.81);
  EXPECT_EQ(ekf.propagate(sampleAt(t0, Vec3::Zero(), f)), PropagateStatus::kFirstSample);
  EXPECT_EQ(ekf.propagate(sampleAt(t0, Vec3::Zero(), f)), PropagateStatus::kNonPositiveDt);
  EXPECT_EQ(ekf.propagate(sampleAt(t0 - 1, Vec3::Zero(), f)), PropagateStatus::kNonPositiveDt);
  EXPECT_EQ(ekf.propagate(sampleAt(t0 + 5'000'000, Vec3::Zero(), f)), PropagateStatus::kPropagated);
  const Mat15 P_before = ekf.covariance();
  const std::int64_t t_before = ekf.t_ns();
  const std::int64_t gap_ns = static_cast<std::int64_t>(1.5e9 * ekf.params().max_imu_dt_s);
  EXPECT_EQ(ekf.propagate(sampleAt(t_before + gap_ns, Vec3(0, 0, 1), f)), PropagateStatus::kGapTooLarge);
  EXPECT_EQ(ekf.t_ns(), t_before);
  EXPECT_EQ(ekf.covariance(), P_before);
  EXPECT_EQ(ekf.counters().imu_non_positive_dt, 2u);
  EXPECT_EQ(ekf.counters().imu_gaps, 1u);
  EXPECT_EQ(ekf.counters().imu_propagated, 1u);
  // initialize() resumes after the gap.
  ekf.initialize(t_before + gap_ns, ekf.state(), ekf.covariance());
  EXPECT_EQ(ekf.propagate(sampleAt(t_before + gap_ns + 5'000'000, Vec3::Zero(), f)), PropagateStatus::kPropagated);
  // Stationary: the state does not move, the covariance grows.
  EXPECT_LE(ekf.state().p_w_b.norm(), 1e-12);
  EXPECT_GT(ekf.covariance()(kPos, kPos), 1e-2);
  // Non-finite samples are refused loudly.
  expectThrowsNaming([&] { ekf.propagate(sampleAt(ekf.t_ns() + 5'000'000, Vec3(kNaN, 0, 0), f)); },
                     "sample.gyro_rad_s");
  expectThrowsNaming([&] { ekf.propagate(sampleAt(ekf.t_ns() + 5'000'000, Vec3::Zero(), Vec3(0, kNaN, 0))); },
                     "sample.accel_m_s2");
}

TEST(ErrorStateEkf, FirstSampleAfterTheStateTimeIsHeldOverTheInterval) {
  ErrorStateEkf ekf;
  ekf.initialize(0, EkfState(), Mat15::Identity() * 1e-2);
  // Specific force 1 m/s^2 along x on top of gravity, held 10 ms from t = 0.
  EXPECT_EQ(ekf.propagate(sampleAt(10'000'000, Vec3::Zero(), Vec3(1.0, 0, 9.81))), PropagateStatus::kPropagated);
  EXPECT_NEAR(ekf.state().v_w.x(), 0.01, 1e-12);
  EXPECT_NEAR(ekf.state().p_w_b.x(), 0.5 * 1e-4, 1e-12);
}

TEST(ErrorStateEkf, UpdateMatchesTextbookJosephFormAndReset) {
  std::mt19937 rng(16);
  for (int i = 0; i < 10; ++i) {
    const EkfState x = randomState(rng);
    Eigen::Matrix<double, 15, 15> L = Eigen::Matrix<double, 15, 15>::Zero();
    for (int r = 0; r < 15; ++r)
      for (int c = 0; c <= r; ++c) L(r, c) = std::normal_distribution<double>(0.0, 0.1)(rng);
    const Mat15 P = L * L.transpose() + 1e-3 * Mat15::Identity();
    ErrorStateEkf ekf;
    ekf.initialize(0, x, P);
    const Vec3 A = x.p_w_b + Vec3(3.0, -2.0, 1.5), lever(0.1, -0.05, 0.2);
    const double sigma = 0.1;
    const EkfPrediction<1> pred = predictRange(x, A, lever);
    const double z = pred.h(0) + 0.15;
    const EkfUpdateResult res = ekf.updateRange(A, lever, z, sigma);
    ASSERT_TRUE(res.accepted());

    // Reference: dense textbook equations.
    const Eigen::Matrix<double, 1, 15> H = fullH(pred);
    const double S = (H * P * H.transpose())(0, 0) + sigma * sigma;
    const Eigen::Matrix<double, 15, 1> K = P * H.transpose() / S;
    const Mat15 IKH = Mat15::Identity() - K * H;
    Mat15 P_ref = IKH * P * IKH.transpose() + K * sigma * sigma * K.transpose();
    const Vec15 dx = K * (z - pred.h(0));
    Mat15 G = Mat15::Identity();
    G.topLeftCorner<3, 3>() = Mat3::Identity() - 0.5 * so3::hat(dx.head<3>());
    P_ref = G * P_ref * G.transpose();

    EXPECT_NEAR(res.innovation, 0.15, 1e-12);
    EXPECT_NEAR(res.normalized_innovation, 0.15 / std::sqrt(S), 1e-12);
    EXPECT_NEAR(res.mahalanobis_sq, 0.15 * 0.15 / S, 1e-12);
    EXPECT_LE(x.retract(dx).local(ekf.state()).norm(), 1e-12);
    // G = Jr(dtheta) differs from I - hat/2 only at O(|dtheta|^2).
    const double tol = 1e-10 + 2.0 * dx.head<3>().squaredNorm() * P.norm();
    EXPECT_LE((ekf.covariance() - P_ref).cwiseAbs().maxCoeff(), tol) << "case " << i;
  }
}

TEST(ErrorStateEkf, GateRejectsOutliersAndCounts) {
  ErrorStateEkf ekf;
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3::Zero(), ImuBias());
  ekf.initialize(0, x0, diagonalCovariance(0.01, 0.05, 0.1, 0.01, 0.001));
  const Vec3 A(5, 5, 2.5), lever(0.1, 0, 0.2);
  const double h = predictRange(x0, A, lever).h(0);
  const EkfUpdateResult bad = ekf.updateRange(A, lever, h + 5.0, 0.1);
  EXPECT_EQ(bad.status, UpdateStatus::kGated);
  EXPECT_FALSE(bad.accepted());
  EXPECT_GT(bad.mahalanobis_sq, ekf.params().gate_chi2_1dof);
  EXPECT_NEAR(bad.innovation, 5.0, 1e-12);
  EXPECT_LE(ekf.state().local(x0).norm(), 0.0);
  const EkfUpdateResult good = ekf.updateRange(A, lever, h + 0.05, 0.1);
  EXPECT_TRUE(good.accepted());
  EXPECT_EQ(ekf.counters().range.gated, 1u);
  EXPECT_EQ(ekf.counters().range.accepted, 1u);
  EXPECT_EQ(ekf.counters().gated(), 1u);
  EXPECT_EQ(ekf.counters().updates(), 1u);

  // Gate disabled: the same outlier goes through.
  EkfParams open;
  open.gate_chi2_1dof = std::numeric_limits<double>::infinity();
  ErrorStateEkf ekf_open(open);
  ekf_open.initialize(0, x0, diagonalCovariance(0.01, 0.05, 0.1, 0.01, 0.001));
  EXPECT_TRUE(ekf_open.updateRange(A, lever, h + 5.0, 0.1).accepted());
}

TEST(ErrorStateEkf, RobustWeightIsIrlsAtThePosteriorResidual) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3::Zero(), ImuBias());
  const Mat15 P0 = diagonalCovariance(0.01, 0.05, 0.1, 0.01, 0.001);
  const Vec3 A(5, 5, 2.5), lever = Vec3::Zero();
  const EkfPrediction<1> pred = predictRange(x0, A, lever);
  const double sigma = 0.1, y = 0.25;
  const double hph = (pred.H * P0.topLeftCorner<6, 6>() * pred.H.transpose())(0, 0);
  const HuberLoss huber;
  // Expected: w1 at y/sigma, w2 at the posterior residual that w1 implies.
  const double w1 = huber.weight(y / sigma);
  const double R1 = sigma * sigma / w1;
  const double w2 = huber.weight(y * R1 / (hph + R1) / sigma);
  for (int iters : {1, 2}) {
    EkfParams params;
    params.robust_iterations = iters;
    params.gate_chi2_1dof = std::numeric_limits<double>::infinity();
    ErrorStateEkf ekf(params);
    ekf.initialize(0, x0, P0);
    const EkfUpdateResult res = ekf.updateRange(A, lever, pred.h(0) + y, sigma, &huber);
    ASSERT_TRUE(res.accepted());
    EXPECT_NEAR(res.weight, iters == 1 ? w1 : w2, 1e-12);
    // The correction equals a Gaussian update with variance sigma^2 / w.
    ErrorStateEkf ref(params);
    ref.initialize(0, x0, P0);
    ref.updateRange(A, lever, pred.h(0) + y, sigma / std::sqrt(res.weight));
    EXPECT_LE(ref.state().local(ekf.state()).norm(), 1e-12);
    EXPECT_LE((ref.covariance() - ekf.covariance()).cwiseAbs().maxCoeff(), 1e-12);
  }
  EXPECT_LT(w1, w2);  // the prior residual overstates the posterior one
}

TEST(ErrorStateEkf, AsymmetricLossDownWeightsOnlyTheNlosSide) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3::Zero(), ImuBias());
  const Mat15 P0 = diagonalCovariance(0.01, 0.03, 0.1, 0.01, 0.001);
  const Vec3 A(5, 5, 2.5), lever = Vec3::Zero();
  const double h = predictRange(x0, A, lever).h(0);
  const AsymmetricLoss nlos(5.0, 0.2);
  EkfParams params;
  params.gate_chi2_1dof = std::numeric_limits<double>::infinity();
  ErrorStateEkf longer(params), shorter(params);
  longer.initialize(0, x0, P0);
  shorter.initialize(0, x0, P0);
  const EkfUpdateResult r_long = longer.updateRange(A, lever, h + 0.6, 0.1, &nlos);
  const EkfUpdateResult r_short = shorter.updateRange(A, lever, h - 0.6, 0.1, &nlos);
  EXPECT_TRUE(r_long.accepted());
  EXPECT_LT(r_long.weight, 0.5);
  EXPECT_TRUE(r_short.accepted());
  EXPECT_DOUBLE_EQ(r_short.weight, 1.0);
  EXPECT_LT(x0.local(longer.state()).segment<3>(kPos).norm(), x0.local(shorter.state()).segment<3>(kPos).norm());
}

TEST(ErrorStateEkf, UltrasonicElevationRowConstrainsHeight) {
  const EkfState x0(Pose3(Mat3::Identity(), Vec3(1, 2, 1)), Vec3::Zero(), ImuBias());
  const Mat15 P0 = diagonalCovariance(0.01, 0.5, 0.1, 0.01, 0.001);
  const Vec3 A(1.5, 2.5, 2.8), lever = Vec3::Zero();
  const double h = predictRange(x0, A, lever).h(0);
  ErrorStateEkf with_elev, without;
  with_elev.initialize(0, x0, P0);
  without.initialize(0, x0, P0);
  const EkfUpdateResult r2 = with_elev.updateUltrasonic(A, lever, h, 0.02, UltrasonicElevation{-1.8, 0.05});
  const EkfUpdateResult r1 = without.updateUltrasonic(A, lever, h, 0.02);
  EXPECT_TRUE(r2.accepted());
  EXPECT_TRUE(r1.accepted());
  EXPECT_LT(with_elev.covariance()(kPos + 2, kPos + 2), 0.06 * 0.06);
  EXPECT_LT(with_elev.covariance()(kPos + 2, kPos + 2), without.covariance()(kPos + 2, kPos + 2));
  EXPECT_EQ(with_elev.counters().ultrasonic.accepted, 1u);
  // A height far from the expectation fails the 2-dof gate.
  const EkfUpdateResult r_bad = with_elev.updateUltrasonic(A, lever, h, 0.02, UltrasonicElevation{-0.8, 0.05});
  EXPECT_EQ(r_bad.status, UpdateStatus::kGated);
  EXPECT_EQ(with_elev.counters().ultrasonic.gated, 1u);
}

TEST(ErrorStateEkf, ZeroWeightSkipsTheUpdate) {
  // A loss that calls everything beyond 1 sigma an outlier outright.
  class Cutoff final : public RobustLoss {
   public:
    double loss(double r) const override { return std::abs(r) < 1.0 ? 0.5 * r * r : 0.5; }
    double derivative(double r) const override { return std::abs(r) < 1.0 ? r : 0.0; }
    std::string name() const override { return "cutoff"; }
  };
  const Cutoff cutoff;
  EkfParams params;
  params.robust_iterations = 1;
  ErrorStateEkf ekf(params);
  const EkfState x0;
  ekf.initialize(0, x0, diagonalCovariance(0.01, 0.05, 0.1, 0.01, 0.001));
  const Vec3 A(3, 0, 0);
  const EkfUpdateResult res = ekf.updateRange(A, Vec3::Zero(), 3.15, 0.1, &cutoff);
  EXPECT_EQ(res.status, UpdateStatus::kZeroWeight);
  EXPECT_EQ(ekf.counters().range.zero_weight, 1u);
  EXPECT_LE(ekf.state().local(x0).norm(), 0.0);
}

TEST(ErrorStateEkf, InvalidArgumentsNameTheParameter) {
  ErrorStateEkf ekf;
  const Vec3 A(1, 2, 3), B(-1, 0, 2), l(0.1, 0, 0);
  EXPECT_THROW(ekf.updateRange(A, l, 2.0, 0.1), std::logic_error);  // not initialized
  ekf.initialize(0, EkfState(), Mat15::Identity() * 0.01);
  expectThrowsNaming([&] { ekf.updateRange(A, l, 2.0, 0.0); }, "sigma_m");
  expectThrowsNaming([&] { ekf.updateRange(A, l, 2.0, -0.1); }, "sigma_m");
  expectThrowsNaming([&] { ekf.updateRange(A, l, 2.0, kNaN); }, "sigma_m");
  expectThrowsNaming([&] { ekf.updateRange(A, l, kNaN, 0.1); }, "range_m");
  expectThrowsNaming([&] { ekf.updateRange(Vec3(kNaN, 0, 0), l, 2.0, 0.1); }, "p_w_anchor");
  expectThrowsNaming([&] { ekf.updateRange(A, Vec3(0, 0, kNaN), 2.0, 0.1); }, "p_b_tag");
  expectThrowsNaming([&] { ekf.updateTdoa(A, B, l, 0.3, 0.0); }, "sigma_m");
  expectThrowsNaming([&] { ekf.updateTdoa(A, B, l, std::numeric_limits<double>::infinity(), 0.1); }, "diff_m");
  expectThrowsNaming([&] { ekf.updateTdoa(A, A, l, 0.3, 0.1); }, "p_w_anchor_a and p_w_anchor_b");
  expectThrowsNaming([&] { ekf.updateTdoa(Vec3(kNaN, 0, 0), B, l, 0.3, 0.1); }, "p_w_anchor_a");
  expectThrowsNaming([&] { ekf.updateTdoa(A, Vec3(kNaN, 0, 0), l, 0.3, 0.1); }, "p_w_anchor_b");
  expectThrowsNaming([&] { ekf.updateUltrasonic(A, l, 2.0, 0.0); }, "sigma_m");
  expectThrowsNaming([&] { ekf.updateUltrasonic(A, Vec3(kNaN, 0, 0), 2.0, 0.02); }, "p_b_us");
  expectThrowsNaming([&] { ekf.updateUltrasonic(A, l, 2.0, 0.02, UltrasonicElevation{-1.0, 0.0}); },
                     "elevation.sigma_h_m");
  expectThrowsNaming([&] { ekf.updateUltrasonic(A, l, 2.0, 0.02, UltrasonicElevation{kNaN, 0.1}); },
                     "elevation.delta_h_m");
  EXPECT_EQ(ekf.counters().range.attempted() + ekf.counters().tdoa.attempted(), 0u);

  // initialize() and the parameters.
  Mat15 not_pd = Mat15::Identity();
  not_pd(4, 4) = -1.0;
  expectThrowsNaming([&] { ekf.initialize(0, EkfState(), not_pd); }, "covariance");
  Mat15 asym = Mat15::Identity();
  asym(0, 1) = 0.5;
  expectThrowsNaming([&] { ekf.initialize(0, EkfState(), asym); }, "covariance");
  EkfState bad_state;
  bad_state.v_w.x() = kNaN;
  expectThrowsNaming([&] { ekf.initialize(0, bad_state, Mat15::Identity()); }, "state");
  EkfParams params;
  params.max_imu_dt_s = 0.0;
  expectThrowsNaming([&] { ErrorStateEkf e(params); }, "max_imu_dt_s");
  params = EkfParams();
  params.robust_iterations = 0;
  expectThrowsNaming([&] { ErrorStateEkf e(params); }, "robust_iterations");
  params = EkfParams();
  params.gate_chi2_1dof = kNaN;
  expectThrowsNaming([&] { ErrorStateEkf e(params); }, "gate_chi2_1dof");
  params = EkfParams();
  params.imu.gyro_noise_density = -1.0;
  expectThrowsNaming([&] { ErrorStateEkf e(params); }, "gyro_noise_density");
}

TEST(ErrorStateEkf, StateEstimateRoundTripAndPoseCovarianceChart) {
  StateEstimate est;
  est.index = 7;
  est.t_ns = 123;
  est.T_w_b = Pose3(so3::exp(Vec3(0.1, -0.2, 0.9)), Vec3(1, 2, 3));
  est.v_w = Vec3(0.3, 0.2, 0.1);
  est.bias = ImuBias(Vec3(0.01, 0.02, 0.03), Vec3(0.001, 0.002, 0.003));
  ErrorStateEkf ekf;
  Mat15 P = diagonalCovariance(0.01, 0.1, 0.1, 0.01, 0.001);
  P(kPos, kPos) = 0.04;  // anisotropic in world x
  ekf.initialize(est, P);
  const StateEstimate out = ekf.estimate();
  EXPECT_EQ(out.index, 7u);
  EXPECT_EQ(out.t_ns, 123);
  EXPECT_LE(out.T_w_b.local(est.T_w_b).norm(), 1e-12);
  EXPECT_EQ(out.v_w, est.v_w);
  EXPECT_EQ(out.bias.vector(), est.bias.vector());
  // rho = R^T dp: the world-x variance shows up along the body image of world x.
  const Mat6 C = ekf.poseCovarianceInRetractionChart();
  const Vec3 ex_b = est.T_w_b.R.transpose() * Vec3::UnitX();
  EXPECT_NEAR(ex_b.dot(C.bottomRightCorner<3, 3>() * ex_b), 0.04, 1e-12);
  EXPECT_NEAR(C(0, 0), 1e-4, 1e-15);
}

}  // namespace
}  // namespace rilo
