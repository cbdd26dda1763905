#include "estimation/factors/bias_factor.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "support/numerical_jacobian.h"

namespace rilo {
namespace {

using sym::B;

ImuParams params(double tau_a_s, double tau_g_s) {
  ImuParams p;
  p.accel_bias_random_walk = 2e-3;
  p.gyro_bias_random_walk = 3e-5;
  p.accel_bias_tau_s = tau_a_s;
  p.gyro_bias_tau_s = tau_g_s;
  return p;
}

TEST(GaussMarkov, ClosedFormTransitionAndVariance) {
  const double q = 2e-3;
  for (double tau : {0.5, 10.0, 300.0}) {
    for (double dt : {1.0 / 800.0, 0.1, 1.0, 20.0}) {
      EXPECT_NEAR(gaussMarkovTransition(dt, tau), std::exp(-dt / tau), 1e-15);
      const double var = q * q * tau / 2.0 * (1.0 - std::exp(-2.0 * dt / tau));
      // The reference loses digits in 1 - exp(.) for dt << tau; the code uses expm1.
      EXPECT_NEAR(gaussMarkovVariance(q, tau, dt), var, 1e-10 * var) << tau << " " << dt;
    }
  }
  // dt >> tau: steady state q^2 tau / 2.
  EXPECT_NEAR(gaussMarkovVariance(q, 2.0, 1e3), q * q * 2.0 / 2.0, 1e-18);
  // dt << tau: random walk to first order, q^2 dt (1 - dt/tau).
  EXPECT_NEAR(gaussMarkovVariance(q, 1e3, 1e-3), q * q * 1e-3 * (1.0 - 1e-6), 1e-12 * q * q * 1e-3);
}

TEST(GaussMarkov, InfiniteTauIsRandomWalk) {
  const double q = 3e-5, inf = ImuParams::kRandomWalk;
  for (double dt : {1.0 / 800.0, 0.5, 30.0}) {
    EXPECT_EQ(gaussMarkovTransition(dt, inf), 1.0);
    EXPECT_NEAR(gaussMarkovVariance(q, inf, dt), q * q * dt, 1e-15 * q * q * dt);
    // And the Gauss-Markov formula tends to it as tau grows.
    EXPECT_NEAR(gaussMarkovVariance(q, 1e9, dt), q * q * dt, 1e-6 * q * q * dt);
    EXPECT_NEAR(gaussMarkovTransition(dt, 1e9), 1.0, 1e-7);
  }
}

TEST(GaussMarkov, DiscreteStepsComposeExactly) {
  // n(t1 + t2) = Phi(t2) n(t1) + w2: Var = Phi(t2)^2 Var(t1) + Var(t2).
  const double q = 1e-3;
  for (double tau : {0.3, 7.0, ImuParams::kRandomWalk}) {
    const double t1 = 0.37, t2 = 1.21;
    const double phi2 = gaussMarkovTransition(t2, tau);
    const double composed = phi2 * phi2 * gaussMarkovVariance(q, tau, t1) + gaussMarkovVariance(q, tau, t2);
    EXPECT_NEAR(gaussMarkovVariance(q, tau, t1 + t2), composed, 1e-13 * composed) << tau;
    EXPECT_NEAR(gaussMarkovTransition(t1, tau) * phi2, gaussMarkovTransition(t1 + t2, tau), 1e-15);
  }
}

TEST(BiasGaussMarkovFactor, TransitionAndSigmaPerAxis) {
  const ImuParams p = params(50.0, ImuParams::kRandomWalk);
  const double dt = 0.8;
  const BiasGaussMarkovFactor f(B(0), B(1), dt, p);
  EXPECT_EQ(f.dim(), 6);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(f.transition()(k), std::exp(-dt / 50.0), 1e-15);
    EXPECT_NEAR(f.sigma()(k), std::sqrt(2e-3 * 2e-3 * 50.0 / 2.0 * (1.0 - std::exp(-2.0 * dt / 50.0))), 1e-15);
    EXPECT_EQ(f.transition()(3 + k), 1.0);
    EXPECT_NEAR(f.sigma()(3 + k), 3e-5 * std::sqrt(dt), 1e-18);
  }
}

TEST(BiasGaussMarkovFactor, ResidualIsWhitenedDecayedDifference) {
  const ImuParams p = params(20.0, 40.0);
  const double dt = 0.5;
  const BiasGaussMarkovFactor f(B(0), B(1), dt, p);
  const ImuBias b_i(Vec3(0.1, -0.2, 0.3), Vec3(0.01, -0.02, 0.03));
  Values x;
  x.insert(B(0), b_i);
  x.insert(B(1), ImuBias(f.transition().cwiseProduct(b_i.vector())));
  Residual r;
  f.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 6);
  EXPECT_LT(r.norm(), 1e-12);  // b_j = Phi b_i: the expected value
  const Vec6 db = (Vec6() << 1e-3, 0, 0, 0, 0, 2e-5).finished();
  x.update(B(1), ImuBias(f.transition().cwiseProduct(b_i.vector()) + db));
  f.evaluate(x, r, nullptr);
  EXPECT_NEAR(r(0), 1e-3 / f.sigma()(0), 1e-9);
  EXPECT_NEAR(r(5), 2e-5 / f.sigma()(5), 1e-9);
  EXPECT_NEAR(f.error(x), 0.5 * r.squaredNorm(), 1e-12);
}

TEST(BiasGaussMarkovFactor, JacobiansMatchNumerical) {
  std::mt19937 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  for (const ImuParams& p : {params(20.0, 40.0), params(ImuParams::kRandomWalk, ImuParams::kRandomWalk)}) {
    for (double dt : {1.0 / 800.0, 0.05, 2.0}) {
      const BiasGaussMarkovFactor f(B(3), B(4), dt, p);
      for (int trial = 0; trial < 5; ++trial) {
        Vec6 bi, bj;
        for (int k = 0; k < 6; ++k) {
          bi(k) = 0.1 * n01(rng);
          bj(k) = 0.1 * n01(rng);
        }
        Values x;
        x.insert(B(3), ImuBias(bi));
        x.insert(B(4), trial == 0 ? ImuBias() : ImuBias(bj));  // also at zero
        EXPECT_TRUE(testing::jacobiansMatch(f, x, 1e-6)) << dt;
      }
    }
  }
}

TEST(BiasGaussMarkovFactor, RejectsBadInput) {
  const ImuParams p;
  for (double dt : {0.0, -0.1, std::nan(""), HUGE_VAL}) {
    try {
      BiasGaussMarkovFactor(B(0), B(1), dt, p);
      ADD_FAILURE() << "dt " << dt << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("dt_s"), std::string::npos) << e.what();
    }
  }
  ImuParams bad;
  bad.accel_bias_random_walk = -1.0;
  try {
    BiasGaussMarkovFactor(B(0), B(1), 0.1, bad);
    ADD_FAILURE() << "negative accel_bias_random_walk accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("accel_bias_random_walk"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rilo
