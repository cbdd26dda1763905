#include "estimation/factors/imu_factor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "sim/trajectory.h"
#include "support/numerical_jacobian.h"

namespace rilo {
namespace {

using sym::B;
using sym::V;
using sym::X;

struct Window {
  PreintegratedImu pim;
  sim::KinematicState s_i, s_j;
};

/// Ideal IMU of the walk over [t0, t0 + T] plus a constant sensor bias,
/// integrated with bias_hat at rate_hz.
Window walkWindow(double t0_s, double T_s, double rate_hz, const ImuParams& params,
                  const ImuBias& sensor_bias = ImuBias(), const ImuBias& bias_hat = ImuBias()) {
  const sim::LissajousWalk walk;
  Window w{PreintegratedImu(params, bias_hat), walk.at(t0_s), walk.at(t0_s + T_s)};
  const int n = std::max(1, static_cast<int>(std::lround(T_s * rate_hz)));
  const double dt = T_s / n;
  for (int k = 0; k < n; ++k) {
    const sim::ImuReading m = sim::idealImu(walk.at(t0_s + k * dt), params.gravity_m_s2);
    w.pim.integrate(m.accel + sensor_bias.accel, m.gyro + sensor_bias.gyro, dt);
  }
  return w;
}

Values trueValues(const Window& w, const ImuBias& b_i, const ImuBias& b_j) {
  Values x;
  x.insert(X(0), w.s_i.T_w_b);
  x.insert(V(0), w.s_i.v_w);
  x.insert(B(0), b_i);
  x.insert(X(1), w.s_j.T_w_b);
  x.insert(V(1), w.s_j.v_w);
  x.insert(B(1), b_j);
  return x;
}

/// Retracts every variable by a random tangent: rotation std rot_rad (norm
/// clamped below 1.5 rad to stay away from the Log cut at pi), others std other.
void perturb(Values& x, std::mt19937& rng, double rot_rad, double other) {
  std::normal_distribution<double> n01(0.0, 1.0);
  for (Key k : x.keys()) {
    Vec6 d;
    for (int i = 0; i < 6; ++i) d(i) = n01(rng);
    if (std::holds_alternative<Pose3>(x.at(k))) {
      d.head<3>() *= rot_rad;
      if (d.head<3>().norm() > 1.5) d.head<3>() *= 1.5 / d.head<3>().norm();
      d.tail<3>() *= other;
    } else {
      d *= other;
    }
    x.retractInPlace(k, d.data());
  }
}

ImuParams gaussMarkovParams() {
  ImuParams p;
  p.accel_bias_tau_s = 2.0;  // short enough that Phi differs visibly from 1
  p.gyro_bias_tau_s = 5.0;
  return p;
}

// ------------------------------------------------------------- true states

TEST(ImuFactor, ResidualsVanishAtTrueStates) {
  const ImuParams params;
  const ImuBias sensor_bias(Vec3(0.04, -0.02, 0.06), Vec3(0.003, -0.001, 0.002));
  // Integrated with a zero bias estimate: the factor corrects to the true b_i.
  for (double rate : {800.0, 6400.0}) {
    const Window w = walkWindow(2.0, 1.0, rate, params, sensor_bias);
    const Values x = trueValues(w, sensor_bias, ImuBias(params.biasTransition(w.pim.dt()).cwiseProduct(sensor_bias.vector())));
    const ImuFactor f9(X(0), V(0), X(1), V(1), B(0), w.pim);
    const CombinedImuFactor f15(X(0), V(0), B(0), X(1), V(1), B(1), w.pim);
    const Vec9 e9 = f9.unwhitenedError(x);
    const Vec15 e15 = f15.unwhitenedError(x);
    EXPECT_EQ((e15.head<9>() - e9).norm(), 0.0);
    EXPECT_LT(e15.tail<6>().norm(), 1e-15);  // b_j = Phi b_i exactly
    // Euler discretization error (first order; see preintegration_test).
    const double scale = 800.0 / rate;
    EXPECT_LT(e9.head<3>().norm(), 2e-4 * scale) << rate;   // rad
    EXPECT_LT(e9.segment<3>(3).norm(), 5e-4 * scale) << rate;  // m
    EXPECT_LT(e9.tail<3>().norm(), 1e-3 * scale) << rate;   // m/s
    Residual r;
    f15.evaluate(x, r, nullptr);
    if (rate > 1000.0) {
      EXPECT_LT(r.norm(), 0.2);  // well inside the noise (|r|^2 ~ chi2(15) would be ~15)
    }
  }
}

TEST(ImuFactor, PredictedStateHasZeroError) {
  // At (T_i, v_i, b_i) arbitrary and (T_j, v_j) = predict(T_i, v_i, b_i), the
  // error vanishes identically: factor and predict() agree.
  std::mt19937 rng(11);
  const Window w = walkWindow(1.0, 2.0, 800.0, gaussMarkovParams(), ImuBias(), ImuBias(Vec6::Constant(0.01)));
  for (int trial = 0; trial < 10; ++trial) {
    Values x = trueValues(w, ImuBias(), ImuBias());
    perturb(x, rng, 1.0, 0.5);
    const ImuBias& b_i = x.bias(B(0));
    const PreintegratedImu::NavState s = w.pim.predict(x.pose(X(0)), x.vec3(V(0)), b_i);
    x.update(X(1), s.T_w_b);
    x.update(V(1), s.v_w);
    const ImuFactor f9(X(0), V(0), X(1), V(1), B(0), w.pim);
    EXPECT_LT(f9.unwhitenedError(x).norm(), 1e-12);
  }
}

// --------------------------------------------------------------- whitening

TEST(ImuFactor, WhiteningIsInverseCholeskyOfResidualCovariance) {
  const Window w = walkWindow(0.0, 2.0, 800.0, gaussMarkovParams());
  const ImuFactor f9(X(0), V(0), X(1), V(1), B(0), w.pim);
  const CombinedImuFactor f15(X(0), V(0), B(0), X(1), V(1), B(1), w.pim);
  // Residual-chart covariance G P G^T, G = blockdiag(Jr(theta), I).
  const Mat3 Jr = so3::rightJacobian(w.pim.theta());
  Mat15 G = Mat15::Identity();
  G.topLeftCorner<3, 3>() = Jr;
  const Mat15 P15 = G * w.pim.combinedCovariance() * G.transpose();
  const Mat9 P9 = G.topLeftCorner<9, 9>() * w.pim.covariance() * G.topLeftCorner<9, 9>().transpose();
  const Mat9 I9 = f9.sqrtInformation() * P9 * f9.sqrtInformation().transpose();
  const Mat15 I15 = f15.sqrtInformation() * P15 * f15.sqrtInformation().transpose();
  EXPECT_LT((I9 - Mat9::Identity()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LT((I15 - Mat15::Identity()).cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_EQ(f15.sqrtInformation().triangularView<Eigen::StrictlyUpper>().toDenseMatrix().norm(), 0.0);
  // Bias transition of the combined factor.
  EXPECT_NEAR(f15.biasTransition()(0), std::exp(-2.0 / 2.0), 1e-12);
  EXPECT_NEAR(f15.biasTransition()(5), std::exp(-2.0 / 5.0), 1e-12);
}

TEST(ImuFactor, RejectsEmptyPreintegration) {
  const PreintegratedImu empty{ImuParams()};
  EXPECT_THROW(ImuFactor(X(0), V(0), X(1), V(1), B(0), empty), std::invalid_argument);
  EXPECT_THROW(CombinedImuFactor(X(0), V(0), B(0), X(1), V(1), B(1), empty), std::invalid_argument);
  // A preintegration that does not keep the covariance the factor needs.
  using Mode = PreintegratedImu::CovarianceMode;
  PreintegratedImu only9(ImuParams(), ImuBias(), Mode::kPreintegration);
  PreintegratedImu only15(ImuParams(), ImuBias(), Mode::kCombined);
  only9.integrate(Vec3(0, 0, 9.81), Vec3::Zero(), 0.01);
  only15.integrate(Vec3(0, 0, 9.81), Vec3::Zero(), 0.01);
  EXPECT_NO_THROW(ImuFactor(X(0), V(0), X(1), V(1), B(0), only9));
  EXPECT_NO_THROW(CombinedImuFactor(X(0), V(0), B(0), X(1), V(1), B(1), only15));
  EXPECT_THROW(ImuFactor(X(0), V(0), X(1), V(1), B(0), only15), std::invalid_argument);
  EXPECT_THROW(CombinedImuFactor(X(0), V(0), B(0), X(1), V(1), B(1), only9), std::invalid_argument);
}

// --------------------------------------------------------------- Jacobians

struct JacobianCase {
  std::string name;
  double T_s;
  double rot_rad, other;  // perturbation of the true states
  ImuBias bias_hat, b_i;
};

TEST(ImuFactor, JacobiansMatchNumericalOnTrajectory) {
  std::mt19937 rng(5);
  const ImuBias sensor_bias(Vec3(0.05, 0.02, -0.04), Vec3(-0.002, 0.004, 0.001));
  const ImuBias other_bias(Vec3(-0.1, 0.3, 0.2), Vec3(0.02, -0.01, 0.03));
  const std::vector<JacobianCase> cases = {
      {"short dt, one sample", 1.0 / 800.0, 0.3, 0.3, ImuBias(), sensor_bias},
      {"1 s, at truth", 1.0, 0.0, 0.0, ImuBias(), ImuBias()},
      {"1 s, random states", 1.0, 0.5, 0.5, sensor_bias, other_bias},
      {"5 s, random states", 5.0, 0.5, 1.0, sensor_bias, other_bias},
      {"5 s, large perturbation", 5.0, 1.0, 2.0, other_bias, sensor_bias},
  };
  for (const ImuParams& params : {ImuParams(), gaussMarkovParams()}) {
    for (const JacobianCase& c : cases) {
      const Window w = walkWindow(1.5, c.T_s, 800.0, params, sensor_bias, c.bias_hat);
      for (int trial = 0; trial < 3; ++trial) {
        Values x = trueValues(w, c.b_i, other_bias);
        perturb(x, rng, c.rot_rad, c.other);
        const ImuFactor f9(X(0), V(0), X(1), V(1), B(0), w.pim);
        const CombinedImuFactor f15(X(0), V(0), B(0), X(1), V(1), B(1), w.pim);
        EXPECT_TRUE(testing::jacobiansMatch(f9, x, 1e-6)) << c.name;
        EXPECT_TRUE(testing::jacobiansMatch(f15, x, 1e-6)) << c.name;
      }
    }
  }
}

TEST(ImuFactor, JacobiansMatchNumericalAtZeroRotation) {
  // Static IMU, identity attitudes: theta = 0, r_R = 0 exactly (small-angle branches).
  for (const ImuParams& params : {ImuParams(), gaussMarkovParams()}) {
    for (double T : {1.0 / 800.0, 1.0}) {
      PreintegratedImu pim(params);
      const int n = std::max(1, static_cast<int>(std::lround(T * 800.0)));
      for (int k = 0; k < n; ++k) pim.integrate(Vec3(0.0, 0.0, params.gravity_m_s2), Vec3::Zero(), T / n);
      ASSERT_EQ(pim.theta().norm(), 0.0);
      Values x;
      x.insert(X(0), Pose3());
      x.insert(V(0), Vec3::Zero());
      x.insert(B(0), ImuBias());
      x.insert(X(1), Pose3());
      x.insert(V(1), Vec3::Zero());
      x.insert(B(1), ImuBias());
      const ImuFactor f9(X(0), V(0), X(1), V(1), B(0), pim);
      const CombinedImuFactor f15(X(0), V(0), B(0), X(1), V(1), B(1), pim);
      Residual r;
      f15.evaluate(x, r, nullptr);
      EXPECT_LT(r.norm(), 1e-6) << T;
      EXPECT_TRUE(testing::jacobiansMatch(f9, x, 1e-6)) << T;
      EXPECT_TRUE(testing::jacobiansMatch(f15, x, 1e-6)) << T;
      // Nonzero biases and positions, rotations still identity.
      x.update(B(0), ImuBias(Vec3(0.1, -0.2, 0.05), Vec3(0.01, 0.02, -0.03)));
      x.update(X(1), Pose3(Mat3::Identity(), Vec3(0.3, -0.1, 0.2)));
      x.update(V(1), Vec3(0.5, 0.0, -0.2));
      EXPECT_TRUE(testing::jacobiansMatch(f9, x, 1e-6)) << T;
      EXPECT_TRUE(testing::jacobiansMatch(f15, x, 1e-6)) << T;
    }
  }
}

}  // namespace
}  // namespace rilo
