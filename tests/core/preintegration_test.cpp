#include "estimation/imu/preintegration.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "sim/trajectory.h"

namespace rilo {
namespace {

constexpr double kG = 9.81;

/// Ideal IMU of the trajectory over [t0, t0 + duration] at rate_hz, plus a
/// constant sensor bias, integrated with bias estimate bias_hat.
PreintegratedImu integrateWalk(const sim::Trajectory& traj, double t0_s, double duration_s, double rate_hz,
                               const ImuParams& params, const ImuBias& sensor_bias = ImuBias(),
                               const ImuBias& bias_hat = ImuBias()) {
  PreintegratedImu pim(params, bias_hat);
  const int n = static_cast<int>(std::lround(duration_s * rate_hz));
  const double dt = duration_s / n;
  for (int k = 0; k < n; ++k) {
    const sim::ImuReading m = sim::idealImu(traj.at(t0_s + k * dt), params.gravity_m_s2);
    pim.integrate(m.accel + sensor_bias.accel, m.gyro + sensor_bias.gyro, dt);
  }
  return pim;
}

struct DeltaErrors {
  double rot_rad, pos_m, vel_m_s;
};

/// Errors of the preintegrated deltas against the exact relative motion.
DeltaErrors errorsAgainstExact(const PreintegratedImu& pim, const sim::Trajectory& traj, double t0_s) {
  const double T = pim.dt();
  const sim::KinematicState si = traj.at(t0_s), sj = traj.at(t0_s + T);
  const Vec3 g_w(0.0, 0.0, -kG);
  const Mat3 Ri_t = si.T_w_b.R.transpose();
  const Mat3 dR = Ri_t * sj.T_w_b.R;
  const Vec3 dp = Ri_t * (sj.T_w_b.p - si.T_w_b.p - si.v_w * T - 0.5 * T * T * g_w);
  const Vec3 dv = Ri_t * (sj.v_w - si.v_w - g_w * T);
  return {so3::log(pim.deltaR().transpose() * dR).norm(), (pim.deltaP() - dp).norm(), (pim.deltaV() - dv).norm()};
}

ImuParams mcParams() {
  ImuParams p;
  p.integration_noise_density = 1e-9;  // negligible (must be > 0); not simulated below
  return p;
}

/// Sample covariance of whitened errors (L^-1 e, L L^T = P): ~ identity if P is right.
template <int N>
Eigen::Matrix<double, N, N> whitenedSampleCovariance(const std::vector<Eigen::Matrix<double, N, 1>>& errors,
                                                     const Eigen::Matrix<double, N, N>& P,
                                                     Eigen::Matrix<double, N, 1>* mean_out) {
  using MatN = Eigen::Matrix<double, N, N>;
  using VecN = Eigen::Matrix<double, N, 1>;
  const Eigen::LLT<MatN> llt(P);
  EXPECT_EQ(llt.info(), Eigen::Success);
  VecN mean = VecN::Zero();
  MatN C = MatN::Zero();
  for (const VecN& e : errors) {
    const VecN z = llt.matrixL().solve(e);
    mean += z;
    C += z * z.transpose();
  }
  const double n = static_cast<double>(errors.size());
  mean /= n;
  *mean_out = mean;
  return C / n - mean * mean.transpose();
}

void expectSymmetricPositiveDefinite(const Eigen::MatrixXd& P, const std::string& what) {
  EXPECT_EQ((P - P.transpose()).cwiseAbs().maxCoeff(), 0.0) << what;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(P);
  EXPECT_GT(eig.eigenvalues().minCoeff(), 0.0) << what;
}

// ------------------------------------------------------------------ ImuParams

TEST(ImuParams, DefaultsAreValid) {
  const ImuParams p;
  EXPECT_NO_THROW(p.validate());
  EXPECT_NEAR(p.gyro_noise_density, 0.008 * M_PI / 180.0, 0.01e-4);  // 0.008 dps/sqrt(Hz)
  EXPECT_NEAR(p.accel_noise_density, 160e-6 * 9.80665, 0.05e-3);    // 160 ug/sqrt(Hz)
}

TEST(ImuParams, ValidateNamesTheBadField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    const char* field;
    double ImuParams::*member;
    std::vector<double> bad;
  };
  const std::vector<Case> cases = {
      {"gyro_noise_density", &ImuParams::gyro_noise_density, {-1e-4, 0.0, nan, HUGE_VAL}},
      {"accel_noise_density", &ImuParams::accel_noise_density, {-1e-3, 0.0, nan}},
      {"gyro_bias_random_walk", &ImuParams::gyro_bias_random_walk, {-1e-5, 0.0, nan}},
      {"accel_bias_random_walk", &ImuParams::accel_bias_random_walk, {-1e-3, nan}},
      {"gyro_bias_tau_s", &ImuParams::gyro_bias_tau_s, {-10.0, 0.0, nan, -HUGE_VAL}},
      {"accel_bias_tau_s", &ImuParams::accel_bias_tau_s, {-10.0, 0.0, nan}},
      {"integration_noise_density", &ImuParams::integration_noise_density, {-1e-4, 0.0, nan}},
      {"gravity_m_s2", &ImuParams::gravity_m_s2, {-9.81, nan, HUGE_VAL}},
      {"gap_threshold_s", &ImuParams::gap_threshold_s, {-0.02, 0.0, nan, HUGE_VAL}},
      {"gap_accel_sigma_m_s2", &ImuParams::gap_accel_sigma_m_s2, {-1.0, nan, HUGE_VAL}},
      {"gap_gyro_sigma_rad_s", &ImuParams::gap_gyro_sigma_rad_s, {-1.0, nan}},
  };
  for (const Case& c : cases) {
    for (double v : c.bad) {
      ImuParams p;
      p.*c.member = v;
      try {
        p.validate();
        ADD_FAILURE() << c.field << " = " << v << " accepted";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find(c.field), std::string::npos) << e.what();
      }
      EXPECT_THROW(PreintegratedImu{p}, std::invalid_argument) << c.field;
    }
  }
  ImuParams rw;
  rw.gyro_bias_tau_s = rw.accel_bias_tau_s = ImuParams::kRandomWalk;
  EXPECT_NO_THROW(rw.validate());
}

TEST(ImuParams, GaussMarkovSigmaParametrization) {
  ImuParams p;
  p.setGyroBiasGaussMarkov(1e-3, 200.0);
  EXPECT_NEAR(p.gyroBiasSigma(), 1e-3, 1e-15);
  EXPECT_DOUBLE_EQ(p.gyro_bias_tau_s, 200.0);
  EXPECT_NEAR(p.gyro_bias_random_walk, 1e-3 * std::sqrt(2.0 / 200.0), 1e-18);
  p.setAccelBiasGaussMarkov(0.02, 50.0);
  EXPECT_NEAR(p.accelBiasSigma(), 0.02, 1e-15);
  // Steady state of the discrete process = sigma^2.
  EXPECT_NEAR(gaussMarkovVariance(p.accel_bias_random_walk, 50.0, 1e4), 0.02 * 0.02, 1e-15);
  p.accel_bias_tau_s = ImuParams::kRandomWalk;
  EXPECT_TRUE(std::isinf(p.accelBiasSigma()));
  EXPECT_THROW(p.setGyroBiasGaussMarkov(-1.0, 10.0), std::invalid_argument);
  EXPECT_THROW(p.setGyroBiasGaussMarkov(1e-3, ImuParams::kRandomWalk), std::invalid_argument);
}

// ---------------------------------------------------------- integration error

TEST(Preintegration, MatchesExactMotionWithFirstOrderConvergence) {
  const sim::LissajousWalk walk;
  const ImuParams params;
  for (double duration : {1.0, 5.0}) {
    const double t0 = 3.0;
    std::vector<DeltaErrors> errs;
    for (double rate : {400.0, 800.0, 1600.0}) {
      errs.push_back(errorsAgainstExact(integrateWalk(walk, t0, duration, rate, params), walk, t0));
    }
    // Euler (sample held over dt) is first order: doubling the rate halves the error.
    for (int k = 0; k + 1 < 3; ++k) {
      EXPECT_NEAR(errs[k].rot_rad / errs[k + 1].rot_rad, 2.0, 0.2) << "duration " << duration << " step " << k;
      EXPECT_NEAR(errs[k].pos_m / errs[k + 1].pos_m, 2.0, 0.2) << "duration " << duration << " step " << k;
      EXPECT_NEAR(errs[k].vel_m_s / errs[k + 1].vel_m_s, 2.0, 0.2) << "duration " << duration << " step " << k;
    }
    // Absolute size at the BMI263's 800 Hz: far below the noise of a consumer IMU.
    const DeltaErrors& e800 = errs[1];
    const double scale = duration;  // errors grow about linearly over the window here
    EXPECT_LT(e800.rot_rad, 2e-4 * scale) << duration;
    EXPECT_LT(e800.vel_m_s, 1e-3 * scale) << duration;
    EXPECT_LT(e800.pos_m, 1e-3 * scale * scale) << duration;
  }
}

TEST(Preintegration, PredictReproducesTrajectory) {
  const sim::LissajousWalk walk;
  const ImuParams params;
  const double t0 = 1.0, T = 1.0;
  const PreintegratedImu pim = integrateWalk(walk, t0, T, 3200.0, params);
  const sim::KinematicState si = walk.at(t0), sj = walk.at(t0 + T);
  const PreintegratedImu::NavState pred = pim.predict(si.T_w_b, si.v_w, ImuBias());
  EXPECT_LT(so3::log(pred.T_w_b.R.transpose() * sj.T_w_b.R).norm(), 1e-4);
  EXPECT_LT((pred.T_w_b.p - sj.T_w_b.p).norm(), 1e-4);
  EXPECT_LT((pred.v_w - sj.v_w).norm(), 2e-4);
}

TEST(Preintegration, ResetAndInputChecks) {
  const ImuParams params;
  PreintegratedImu pim(params);
  pim.integrate(Vec3(0.1, 0.2, 9.8), Vec3(0.3, -0.2, 0.1), 0.01);
  EXPECT_EQ(pim.numSamples(), 1);
  EXPECT_GT(pim.deltaV().norm(), 0.0);
  const ImuBias b(Vec3(0.1, 0.0, 0.0), Vec3(0.0, 0.01, 0.0));
  pim.reset(b);
  EXPECT_EQ(pim.numSamples(), 0);
  EXPECT_EQ(pim.dt(), 0.0);
  EXPECT_EQ(pim.xi().norm(), 0.0);
  EXPECT_EQ(pim.covariance().norm(), 0.0);
  EXPECT_EQ(pim.biasHat().vector(), b.vector());
  EXPECT_THROW(pim.integrate(Vec3::Zero(), Vec3::Zero(), 0.0), std::invalid_argument);
  EXPECT_THROW(pim.integrate(Vec3::Zero(), Vec3::Zero(), -1e-3), std::invalid_argument);
  EXPECT_THROW(pim.integrate(Vec3::Zero(), Vec3::Zero(), std::nan("")), std::invalid_argument);
  EXPECT_THROW(pim.integrate(Vec3(std::nan(""), 0, 0), Vec3::Zero(), 1e-3), std::invalid_argument);
  EXPECT_EQ(pim.numSamples(), 0);
}

// ------------------------------------------------------------ bias correction

TEST(Preintegration, BiasCorrectionIsSecondOrderAccurate) {
  const sim::LissajousWalk walk;
  const ImuParams params;
  const ImuBias sensor_bias(Vec3(0.05, -0.03, 0.08), Vec3(0.004, -0.002, 0.003));
  const ImuBias b1(Vec3(0.02, 0.01, -0.03), Vec3(0.001, 0.002, -0.001));
  const Vec6 direction = (Vec6() << 0.3, -0.2, 0.25, 0.02, -0.015, 0.03).finished();
  for (double duration : {0.5, 3.0}) {
    const PreintegratedImu pim1 = integrateWalk(walk, 2.0, duration, 800.0, params, sensor_bias, b1);
    // Correction error against a fresh integration at b2 = b1 + s * direction.
    auto correctionError = [&](double s) {
      const ImuBias b2(b1.vector() + s * direction);
      const PreintegratedImu pim2 = integrateWalk(walk, 2.0, duration, 800.0, params, sensor_bias, b2);
      const PreintegratedImu::Delta d = pim1.biasCorrectedDelta(b2);
      Vec9 e;
      e << so3::log(d.R.transpose() * pim2.deltaR()), d.p_m - pim2.deltaP(), d.v_m_s - pim2.deltaV();
      Vec9 uncorrected;
      uncorrected << so3::log(pim1.deltaR().transpose() * pim2.deltaR()), pim1.deltaP() - pim2.deltaP(),
          pim1.deltaV() - pim2.deltaV();
      EXPECT_LT(e.norm(), 0.1 * uncorrected.norm()) << "s " << s;
      return e;
    };
    const Vec9 e1 = correctionError(1.0), e2 = correctionError(0.5), e4 = correctionError(0.25);
    // O(|delta|^2): halving delta quarters the error (rotation, position, velocity separately).
    for (int blk = 0; blk < 3; ++blk) {
      const double r12 = e1.segment<3>(3 * blk).norm() / e2.segment<3>(3 * blk).norm();
      const double r24 = e2.segment<3>(3 * blk).norm() / e4.segment<3>(3 * blk).norm();
      EXPECT_NEAR(r12, 4.0, 0.4) << "duration " << duration << " block " << blk;
      EXPECT_NEAR(r24, 4.0, 0.4) << "duration " << duration << " block " << blk;
    }
  }
}

TEST(Preintegration, ZeroBiasChangeIsExact) {
  const sim::LissajousWalk walk;
  const ImuBias b(Vec3(0.1, 0.2, 0.3), Vec3(0.01, 0.02, 0.03));
  const PreintegratedImu pim = integrateWalk(walk, 0.0, 1.0, 800.0, ImuParams(), ImuBias(), b);
  const PreintegratedImu::Delta d = pim.biasCorrectedDelta(b);
  EXPECT_EQ((d.theta_rad - pim.theta()).norm(), 0.0);
  EXPECT_EQ((d.p_m - pim.deltaP()).norm(), 0.0);
  EXPECT_EQ((d.v_m_s - pim.deltaV()).norm(), 0.0);
  EXPECT_EQ(pim.J_xi_ba().topRows<3>().norm(), 0.0);  // rotation does not depend on the accel bias
}

TEST(Preintegration, BiasCorrectionBeyondPi) {
  // Constant rates turning 4.5 rad in 3 s: theta passes pi (Jr^-1 is fine up to 2 pi).
  const ImuParams params;
  const Vec3 w(1.4, 0.4, -0.3), f(0.3, -0.2, 9.7);
  const ImuBias b1;
  const Vec6 direction = (Vec6() << 0.2, 0.1, -0.3, 0.01, -0.02, 0.015).finished();
  auto run = [&](const ImuBias& b) {
    PreintegratedImu pim(params, b);
    for (int k = 0; k < 2400; ++k) pim.integrate(f, w, 1.0 / 800.0);
    return pim;
  };
  const PreintegratedImu pim1 = run(b1);
  ASSERT_GT(pim1.theta().norm(), M_PI);
  EXPECT_LT(so3::log(pim1.deltaR().transpose() * so3::exp(3.0 * w)).norm(), 1e-12);
  auto correctionError = [&](double s) {
    const ImuBias b2(b1.vector() + s * direction);
    const PreintegratedImu pim2 = run(b2);
    const PreintegratedImu::Delta d = pim1.biasCorrectedDelta(b2);
    Vec9 e;
    e << so3::log(d.R.transpose() * pim2.deltaR()), d.p_m - pim2.deltaP(), d.v_m_s - pim2.deltaV();
    return e.norm();
  };
  EXPECT_NEAR(correctionError(0.1) / correctionError(0.05), 4.0, 0.4);
}

// ----------------------------------------------------------------- covariance

TEST(Preintegration, GapIntervalAddsTheUnmeasuredMotionVariance) {
  // One interval at rest, theta = 0 (Jr = I): the covariance is exactly the
  // input variances, so the gap term shows as a difference of (sigma dt)^2.
  ImuParams no_gap_noise;
  no_gap_noise.gap_accel_sigma_m_s2 = no_gap_noise.gap_gyro_sigma_rad_s = 0.0;
  const ImuParams with_gap_noise;  // defaults: 2 m/s^2, 0.5 rad/s beyond 0.02 s
  const Vec3 f_b(0.0, 0.0, kG), w_b = Vec3::Zero();
  for (double dt : {0.01, 0.5}) {
    PreintegratedImu a(no_gap_noise), b(with_gap_noise);
    a.integrate(f_b, w_b, dt);
    b.integrate(f_b, w_b, dt);
    const Mat9 d = b.covariance() - a.covariance();
    const Eigen::Matrix<double, 15, 15> dc = b.combinedCovariance() - a.combinedCovariance();
    if (dt <= with_gap_noise.gap_threshold_s) {
      EXPECT_EQ(d.norm(), 0.0) << "no gap at dt " << dt;
      EXPECT_EQ(dc.norm(), 0.0);
      continue;
    }
    const double sa2 = 4.0, sg2 = 0.25, dt2 = dt * dt;
    const Mat3 I = Mat3::Identity();
    EXPECT_TRUE((d.block<3, 3>(0, 0).isApprox(sg2 * dt2 * I, 1e-9))) << d.block<3, 3>(0, 0);  // rotation
    EXPECT_TRUE((d.block<3, 3>(3, 3).isApprox(sa2 * dt2 * dt2 * 0.25 * I, 1e-9)));  // position
    EXPECT_TRUE((d.block<3, 3>(3, 6).isApprox(sa2 * dt2 * dt * 0.5 * I, 1e-9)));  // p-v
    EXPECT_TRUE((d.block<3, 3>(6, 6).isApprox(sa2 * dt2 * I, 1e-9))) << d.block<3, 3>(6, 6);  // velocity
    EXPECT_TRUE((dc.topLeftCorner<9, 9>().isApprox(d, 1e-9)));
  }
}

TEST(Preintegration, CovarianceModesKeepTheSameMatrices) {
  const sim::LissajousWalk walk;
  using Mode = PreintegratedImu::CovarianceMode;
  const PreintegratedImu both = integrateWalk(walk, 1.0, 0.5, 800.0, ImuParams());
  PreintegratedImu only9(ImuParams(), ImuBias(), Mode::kPreintegration);
  PreintegratedImu only15(ImuParams(), ImuBias(), Mode::kCombined);
  const double dt = 0.5 / 400;  // as in integrateWalk, so the samples are bit-identical
  for (int k = 0; k < 400; ++k) {
    const sim::ImuReading m = sim::idealImu(walk.at(1.0 + k * dt), kG);
    only9.integrate(m.accel, m.gyro, dt);
    only15.integrate(m.accel, m.gyro, dt);
  }
  EXPECT_EQ((only9.covariance() - both.covariance()).norm(), 0.0);
  EXPECT_EQ((only15.combinedCovariance() - both.combinedCovariance()).norm(), 0.0);
  EXPECT_EQ((only9.xi() - both.xi()).norm(), 0.0);
  EXPECT_EQ((only15.J_xi_bg() - both.J_xi_bg()).norm(), 0.0);
  EXPECT_THROW(only9.combinedCovariance(), std::logic_error);
  EXPECT_THROW(only15.covariance(), std::logic_error);
}


TEST(Preintegration, CovarianceMatchesMonteCarlo) {
  const sim::LissajousWalk walk;
  const ImuParams params = mcParams();
  const double rate = 800.0, dt = 1.0 / rate, t0 = 2.0;
  const int n_samples = 80, n_runs = 2000;  // 0.1 s window
  std::vector<sim::ImuReading> ideal;
  for (int k = 0; k < n_samples; ++k) ideal.push_back(sim::idealImu(walk.at(t0 + k * dt), kG));
  PreintegratedImu clean(params);
  for (const auto& m : ideal) clean.integrate(m.accel, m.gyro, dt);

  std::mt19937 rng(42);
  std::normal_distribution<double> n01(0.0, 1.0);
  const double sa = params.accel_noise_density / std::sqrt(dt), sg = params.gyro_noise_density / std::sqrt(dt);
  std::vector<Vec9> errors;
  PreintegratedImu noisy(params);
  for (int run = 0; run < n_runs; ++run) {
    noisy.reset(ImuBias());
    for (const auto& m : ideal) {
      noisy.integrate(m.accel + sa * Vec3(n01(rng), n01(rng), n01(rng)),
                      m.gyro + sg * Vec3(n01(rng), n01(rng), n01(rng)), dt);
    }
    errors.push_back(noisy.xi() - clean.xi());
  }
  Vec9 mean;
  const Mat9 C = whitenedSampleCovariance<9>(errors, clean.covariance(), &mean);
  // Whitened sample covariance ~ I: entry std-dev ~ 0.03 (diagonal) and 0.022 (off) for 2000 runs.
  EXPECT_LT((C - Mat9::Identity()).cwiseAbs().maxCoeff(), 0.15) << C;
  EXPECT_LT(mean.cwiseAbs().maxCoeff(), 0.1) << mean.transpose();
  // The matrix used is exactly the propagated one: all blocks consistent.
  expectSymmetricPositiveDefinite(clean.covariance(), "9x9");
}

TEST(Preintegration, CombinedCovarianceMatchesMonteCarloWithBiasDrift) {
  const sim::LissajousWalk walk;
  ImuParams params = mcParams();
  // Strong bias processes so that their effect is comparable to the white
  // noise in a 0.1 s window: Gauss-Markov accel bias, random-walk gyro bias.
  params.accel_bias_random_walk = 0.03;
  params.accel_bias_tau_s = 0.05;
  params.gyro_bias_random_walk = 5e-3;
  params.gyro_bias_tau_s = ImuParams::kRandomWalk;
  const double rate = 800.0, dt = 1.0 / rate, t0 = 2.0;
  const int n_samples = 80, n_runs = 2000;
  std::vector<sim::ImuReading> ideal;
  for (int k = 0; k < n_samples; ++k) ideal.push_back(sim::idealImu(walk.at(t0 + k * dt), kG));
  PreintegratedImu clean(params);
  for (const auto& m : ideal) clean.integrate(m.accel, m.gyro, dt);

  std::mt19937 rng(7);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto randn3 = [&] { return Vec3(n01(rng), n01(rng), n01(rng)); };
  const double sa = params.accel_noise_density / std::sqrt(dt), sg = params.gyro_noise_density / std::sqrt(dt);
  const Vec6 phi = params.biasTransition(dt), q_std = params.biasDiscreteVariance(dt).cwiseSqrt();
  std::vector<Vec15> errors;
  PreintegratedImu noisy(params);
  for (int run = 0; run < n_runs; ++run) {
    noisy.reset(ImuBias());  // b_i = 0 is the bias estimate and the true bias at i
    Vec6 n = Vec6::Zero();   // bias deviation inside the window
    for (const auto& m : ideal) {
      noisy.integrate(m.accel + n.head<3>() + sa * randn3(), m.gyro + n.tail<3>() + sg * randn3(), dt);
      n = phi.cwiseProduct(n) + q_std.cwiseProduct((Vec6() << randn3(), randn3()).finished());
    }
    Vec15 e;
    e << clean.xi() - noisy.xi(), n;  // residual convention: [xi_true - xi_meas; b_j - Phi b_i]
    errors.push_back(e);
  }
  const Mat15 P = clean.combinedCovariance();
  expectSymmetricPositiveDefinite(P, "15x15");
  Vec15 mean;
  const Mat15 C = whitenedSampleCovariance<15>(errors, P, &mean);
  EXPECT_LT((C - Mat15::Identity()).cwiseAbs().maxCoeff(), 0.15) << C;
  EXPECT_LT(mean.cwiseAbs().maxCoeff(), 0.1) << mean.transpose();
  // The bias drift makes the preintegration block larger than the white-noise one.
  const Eigen::SelfAdjointEigenSolver<Mat9> eig(P.topLeftCorner<9, 9>() - clean.covariance());
  EXPECT_GT(eig.eigenvalues().minCoeff(), -1e-18);
  EXPECT_GT((P.topLeftCorner<9, 9>() - clean.covariance()).norm(), 0.1 * clean.covariance().norm());
}

TEST(Preintegration, CovariancesSymmetricPositiveDefiniteAndBiasBlockExact) {
  const sim::LissajousWalk walk;
  for (double tau : {30.0, ImuParams::kRandomWalk}) {
    ImuParams params;
    params.gyro_bias_tau_s = params.accel_bias_tau_s = tau;
    for (double duration : {1.0 / 800.0, 1.0, 5.0}) {
      const PreintegratedImu pim = integrateWalk(walk, 0.5, duration, 800.0, params);
      expectSymmetricPositiveDefinite(pim.covariance(), "9x9 T=" + std::to_string(duration));
      const Mat15 P = pim.combinedCovariance();
      expectSymmetricPositiveDefinite(P, "15x15 T=" + std::to_string(duration));
      // Per-sample Gauss-Markov steps compose to the exact discrete variance over T.
      const Vec6 var = params.biasDiscreteVariance(pim.dt());
      for (int k = 0; k < 6; ++k) EXPECT_NEAR(P(9 + k, 9 + k), var(k), 1e-9 * var(k)) << k;
      const Mat6 P_bb = P.bottomRightCorner<6, 6>();
      EXPECT_EQ((P_bb - Mat6(P_bb.diagonal().asDiagonal())).norm(), 0.0);  // diagonal
    }
  }
}

TEST(Preintegration, RefusesWindowsRotatingTowardTheTangentSingularity) {
  PreintegratedImu pim{ImuParams()};
  const Vec3 spin(0.0, 0.0, 2.0);  // rad/s
  const Vec3 f(0.0, 0.0, 9.81);
  // 2.5 s at 2 rad/s = 5 rad < 0.9 * 2 pi: fine.
  for (int k = 0; k < 2000; ++k) pim.integrate(f, spin, 1.25e-3);
  EXPECT_NEAR(pim.theta().norm(), 5.0, 1e-9);
  // Another 0.5 s passes 0.9 * 2 pi = 5.65 rad: refused with a clear error.
  EXPECT_THROW(
      for (int k = 0; k < 400; ++k) pim.integrate(f, spin, 1.25e-3), std::domain_error);
}

}  // namespace
}  // namespace rilo
