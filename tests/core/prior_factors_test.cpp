#include "estimation/factors/prior_factors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include "estimation/noise/huber_loss.h"
#include "math/so3.h"
#include "support/numerical_jacobian.h"
#include "support/random_states.h"
#include "support/test_losses.h"

namespace rilo {
namespace {

using sym::B;
using sym::L;
using sym::V;
using sym::X;
using testing::TestAsymmetric;
using testing::randomPose;
using testing::randomRotation;
using testing::randomVec;

template <int N>
Eigen::Matrix<double, N, N> randomSpd(std::mt19937& rng, double scale) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix<double, N, N> A;
  for (int i = 0; i < N; ++i)
    for (int j = 0; j < N; ++j) A(i, j) = n(rng);
  return scale * (A * A.transpose() + 0.5 * Eigen::Matrix<double, N, N>::Identity());
}

// ----------------------------------------------------------------- SqrtInformation
TEST(SqrtInformation, FromCovarianceIsUpperTriangularInverseRoot) {
  std::mt19937 rng(40);
  for (int i = 0; i < 20; ++i) {
    const Mat6 cov = randomSpd<6>(rng, 0.01);
    const Mat6 U = SqrtInformation<6>::fromCovariance(cov).U;
    EXPECT_LE(U.triangularView<Eigen::StrictlyLower>().toDenseMatrix().cwiseAbs().maxCoeff(), 0.0);
    EXPECT_GT(U.diagonal().minCoeff(), 0.0);
    EXPECT_LE((U.transpose() * U * cov - Mat6::Identity()).cwiseAbs().maxCoeff(), 1e-9);
  }
  const Vec3 sigmas(0.1, 0.2, 0.5);
  const Mat3 U = SqrtInformation<3>::fromSigmas(sigmas).U;
  EXPECT_LE((U - Vec3(10, 5, 2).asDiagonal().toDenseMatrix()).norm(), 1e-12);
  // Same as the diagonal covariance.
  const Mat3 Uc = SqrtInformation<3>::fromCovariance(Vec3(0.01, 0.04, 0.25).asDiagonal().toDenseMatrix()).U;
  EXPECT_LE((U - Uc).norm(), 1e-10);
}

TEST(SqrtInformation, RejectsBadCovariances) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Mat3 asym = Mat3::Identity();
  asym(0, 1) = 0.5;  // (1, 0) stays 0
  EXPECT_THROW(SqrtInformation<3>::fromCovariance(asym), std::invalid_argument);
  Mat3 indefinite = Mat3::Identity();
  indefinite(2, 2) = -1.0;
  EXPECT_THROW(SqrtInformation<3>::fromCovariance(indefinite), std::invalid_argument);
  Mat3 singular;
  singular << 1, 1, 0, 1, 1, 0, 0, 0, 1;
  EXPECT_THROW(SqrtInformation<3>::fromCovariance(singular), std::invalid_argument);
  EXPECT_THROW(SqrtInformation<3>::fromCovariance(Mat3::Zero()), std::invalid_argument);
  Mat3 with_nan = Mat3::Identity();
  with_nan(1, 1) = nan;
  EXPECT_THROW(SqrtInformation<3>::fromCovariance(with_nan), std::invalid_argument);
  EXPECT_THROW(SqrtInformation<3>::fromSigmas(Vec3(0.1, 0.0, 0.1)), std::invalid_argument);
  EXPECT_THROW(SqrtInformation<3>::fromSigmas(Vec3(0.1, -1.0, 0.1)), std::invalid_argument);
  EXPECT_THROW(SqrtInformation<3>::fromSigmas(Vec3(0.1, nan, 0.1)), std::invalid_argument);
  // Tiny but well-conditioned covariances are fine (rad^2 of a good attitude).
  EXPECT_NO_THROW(SqrtInformation<3>::fromCovariance(1e-12 * Mat3::Identity()));
}

// ----------------------------------------------------------------- PriorPose3Factor
TEST(PriorPose3Factor, ResidualAtKnownConfiguration) {
  const Pose3 T_prior;  // identity
  Vec6 sigmas;
  sigmas << 0.05, 0.05, 0.05, 0.5, 0.5, 0.5;
  const PriorPose3Factor f(X(0), T_prior, sigmas);
  Values x;
  x.insert(X(0), Pose3(so3::exp(Vec3(0, 0, 0.1)), Vec3(1, 2, 3)));
  Residual r;
  f.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 6);
  Vec6 expected;
  expected << 0, 0, 2.0, 2.0, 4.0, 6.0;
  EXPECT_LE((r - expected).cwiseAbs().maxCoeff(), 1e-10);

  // Non-identity prior: translation error is expressed in the prior's frame.
  const Pose3 T_p(so3::exp(Vec3(0, 0, M_PI / 2)), Vec3(1, 0, 0));
  const PriorPose3Factor g(X(0), T_p, Vec6::Ones().eval());
  Values y;
  y.insert(X(0), Pose3(T_p.R, Vec3(1, 1, 0)));  // 1 m along world y = prior body x
  g.evaluate(y, r, nullptr);
  expected << 0, 0, 0, 1, 0, 0;
  EXPECT_LE((r - expected).cwiseAbs().maxCoeff(), 1e-12);
  y.update(X(0), T_p);
  g.evaluate(y, r, nullptr);
  EXPECT_LE(r.cwiseAbs().maxCoeff(), 1e-12);
}

TEST(PriorPose3Factor, ErrorIsHalfMahalanobis) {
  std::mt19937 rng(41);
  const Mat6 cov = randomSpd<6>(rng, 0.02);
  const Pose3 T_prior = randomPose(rng, 3.0);
  const PriorPose3Factor f(X(0), T_prior, cov);
  const Pose3 T = randomPose(rng, 3.0);
  Values x;
  x.insert(X(0), T);
  const Vec6 e = T_prior.local(T);
  EXPECT_NEAR(f.error(x), 0.5 * e.dot(cov.ldlt().solve(e)), 1e-8 * std::max(1.0, f.error(x)));
}

TEST(PriorPose3Factor, JacobiansMatch) {
  std::mt19937 rng(42);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_prior = randomPose(rng, 3.0);
    // Mix of states near the prior and arbitrary ones (rotation error up to ~pi).
    const Pose3 T = (i % 2 == 0) ? T_prior.retract((Vec6() << randomVec(rng, 0.2), randomVec(rng, 0.5)).finished())
                                 : randomPose(rng, 3.0);
    if (so3::log(T_prior.R.transpose() * T.R).norm() > 3.0) continue;  // Log is not smooth at pi
    Values x;
    x.insert(X(0), T);
    EXPECT_TRUE(testing::jacobiansMatch(PriorPose3Factor(X(0), T_prior, randomSpd<6>(rng, 0.05)), x, 1e-6)) << i;
    Vec6 sigmas;
    sigmas << 0.01, 0.02, 0.03, 0.1, 0.2, 0.3;
    EXPECT_TRUE(testing::jacobiansMatch(PriorPose3Factor(X(0), T_prior, sigmas), x, 1e-6)) << i;
  }
  // At the prior itself (zero rotation error) and with zero rotation everywhere.
  Values x;
  x.insert(X(0), Pose3());
  EXPECT_TRUE(testing::jacobiansMatch(PriorPose3Factor(X(0), Pose3(), Vec6::Constant(0.1).eval()), x, 1e-6));
  x.update(X(0), Pose3(Mat3::Identity(), Vec3(1, -2, 3)));
  EXPECT_TRUE(testing::jacobiansMatch(PriorPose3Factor(X(0), Pose3(), Vec6::Constant(0.1).eval()), x, 1e-6));
}

TEST(PriorPose3Factor, InvalidArgumentsThrow) {
  Vec6 sigmas = Vec6::Constant(0.1);
  sigmas(4) = 0.0;
  EXPECT_THROW(PriorPose3Factor(X(0), Pose3(), sigmas), std::invalid_argument);
  Mat6 cov = Mat6::Identity();
  cov(0, 5) = 0.3;
  EXPECT_THROW(PriorPose3Factor(X(0), Pose3(), cov), std::invalid_argument);
  cov = Mat6::Identity();
  cov(3, 3) = -0.1;
  EXPECT_THROW(PriorPose3Factor(X(0), Pose3(), cov), std::invalid_argument);
  try {
    PriorPose3Factor(X(0), Pose3(), cov);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("PriorPose3Factor: covariance"), std::string::npos) << e.what();
  }
  const Pose3 bad(Mat3::Identity(), Vec3(0, std::numeric_limits<double>::quiet_NaN(), 0));
  EXPECT_THROW(PriorPose3Factor(X(0), bad, Vec6::Ones().eval()), std::invalid_argument);
}

// ----------------------------------------------------------------- PriorVec3Factor
TEST(PriorVec3Factor, ResidualJacobianAndErrors) {
  const PriorVec3Factor f(V(2), Vec3(1, 0, -1), Vec3(0.5, 0.5, 0.25));
  Values x;
  x.insert(V(2), Vec3(2, 0.5, -1.5));
  Residual r;
  f.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 3);
  EXPECT_LE((r - Vec3(2, 1, -2)).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_NEAR(f.error(x), 4.5, 1e-12);
  EXPECT_TRUE(testing::jacobiansMatch(f, x, 1e-6));

  std::mt19937 rng(43);
  for (int i = 0; i < 50; ++i) {
    const Mat3 cov = randomSpd<3>(rng, 0.1);
    const Vec3 prior = randomVec(rng, 5.0);
    const PriorVec3Factor g(L(i), prior, cov);
    Values y;
    y.insert(L(i), randomVec(rng, 5.0));
    EXPECT_TRUE(testing::jacobiansMatch(g, y, 1e-6));
    const Vec3 e = y.vec3(L(i)) - prior;
    EXPECT_NEAR(g.error(y), 0.5 * e.dot(cov.ldlt().solve(e)), 1e-8 * std::max(1.0, g.error(y)));
  }
  EXPECT_EQ(f.prior(), Vec3(1, 0, -1));
  EXPECT_LE((f.sqrtInformation() - Vec3(2, 2, 4).asDiagonal().toDenseMatrix()).norm(), 1e-12);
}

TEST(PriorVec3Factor, RobustLossAndInvalidArguments) {
  const PriorVec3Factor plain(L(0), Vec3::Zero(), Vec3::Constant(0.1).eval());
  const PriorVec3Factor robust(L(0), Vec3::Zero(), Vec3::Constant(0.1).eval(), std::make_shared<HuberLoss>(1.0));
  Values x;
  x.insert(L(0), Vec3(0.3, 0.4, 0.0));  // |r| = 5
  EXPECT_NEAR(plain.error(x), 12.5, 1e-9);
  EXPECT_NEAR(robust.error(x), 4.5, 1e-9);
  EXPECT_THROW(PriorVec3Factor(L(0), Vec3::Zero(), Vec3(0.1, 0.1, -0.1)), std::invalid_argument);
  EXPECT_THROW(PriorVec3Factor(L(0), Vec3::Zero(), Mat3::Zero().eval()), std::invalid_argument);
  Mat3 asym = Mat3::Identity();
  asym(2, 0) = 0.1;
  EXPECT_THROW(PriorVec3Factor(L(0), Vec3::Zero(), asym), std::invalid_argument);
  EXPECT_THROW(PriorVec3Factor(L(0), Vec3(std::numeric_limits<double>::infinity(), 0, 0), Vec3::Ones().eval()),
               std::invalid_argument);
}

TEST(PriorFactors, VectorPriorsRejectAsymmetricLoss) {
  auto asym = std::make_shared<TestAsymmetric>();
  EXPECT_THROW(PriorPose3Factor(X(0), Pose3(), Vec6::Ones().eval(), asym), std::invalid_argument);
  EXPECT_THROW(PriorVec3Factor(V(0), Vec3::Zero(), Vec3::Ones().eval(), asym), std::invalid_argument);
  EXPECT_THROW(PriorBiasFactor(B(0), ImuBias(), Vec6::Ones().eval(), asym), std::invalid_argument);
  // Symmetric losses are fine on vector priors; any loss on the scalar height band.
  EXPECT_NO_THROW(PriorPose3Factor(X(0), Pose3(), Vec6::Ones().eval(), std::make_shared<HuberLoss>(1.0)));
  EXPECT_NO_THROW(HeightBandFactor(X(0), 0.0, 1.0, 0.1, asym));
}

// ----------------------------------------------------------------- PriorBiasFactor
TEST(PriorBiasFactor, ResidualJacobianAndInvalidArguments) {
  const ImuBias prior(Vec3(0.1, 0, 0), Vec3(0, 0.01, 0));
  Vec6 sigmas;
  sigmas << 0.1, 0.1, 0.1, 0.01, 0.01, 0.01;
  const PriorBiasFactor f(B(0), prior, sigmas);
  Values x;
  x.insert(B(0), ImuBias(Vec3(0.2, 0, 0), Vec3(0, 0.03, -0.01)));
  Residual r;
  f.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 6);
  Vec6 expected;
  expected << 1, 0, 0, 0, 2, -1;
  EXPECT_LE((r - expected).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_TRUE(testing::jacobiansMatch(f, x, 1e-6));

  std::mt19937 rng(44);
  for (int i = 0; i < 20; ++i) {
    const PriorBiasFactor g(B(i), ImuBias(randomVec(rng, 0.1), randomVec(rng, 0.01)), randomSpd<6>(rng, 1e-3));
    Values y;
    y.insert(B(i), ImuBias(randomVec(rng, 0.1), randomVec(rng, 0.01)));
    EXPECT_TRUE(testing::jacobiansMatch(g, y, 1e-6));
  }

  sigmas(5) = -0.01;
  EXPECT_THROW(PriorBiasFactor(B(0), prior, sigmas), std::invalid_argument);
  Mat6 cov = Mat6::Identity();
  cov(5, 5) = 0.0;
  EXPECT_THROW(PriorBiasFactor(B(0), prior, cov), std::invalid_argument);
}

// ----------------------------------------------------------------- HeightBandFactor
TEST(HeightBandFactor, ZeroInsideLinearOutsideContinuous) {
  const HeightBandFactor f(X(0), 1.0, 1.8, 0.1);
  auto residualAt = [&f](double z) {
    Values x;
    x.insert(X(0), Pose3(so3::exp(Vec3(0.3, 0.2, 1.0)), Vec3(5, -3, z)));
    Residual r;
    f.evaluate(x, r, nullptr);
    return r(0);
  };
  EXPECT_EQ(residualAt(1.0), 0.0);
  EXPECT_EQ(residualAt(1.4), 0.0);
  EXPECT_EQ(residualAt(1.8), 0.0);
  EXPECT_NEAR(residualAt(2.1), 3.0, 1e-12);    // above: positive
  EXPECT_NEAR(residualAt(0.5), -5.0, 1e-12);   // below: negative
  // Continuous at both edges.
  EXPECT_NEAR(residualAt(1.8 + 1e-9), 0.0, 1e-7);
  EXPECT_NEAR(residualAt(1.0 - 1e-9), 0.0, 1e-7);
  EXPECT_DOUBLE_EQ(f.zMin(), 1.0);
  EXPECT_DOUBLE_EQ(f.zMax(), 1.8);
  EXPECT_DOUBLE_EQ(f.sigma(), 0.1);
}

TEST(HeightBandFactor, JacobiansMatchAwayFromEdges) {
  std::mt19937 rng(45);
  std::uniform_real_distribution<double> z_dist(-2.0, 5.0);
  int outside = 0;
  for (int i = 0; i < 200; ++i) {
    const double z = z_dist(rng);
    if (std::abs(z - 1.0) < 1e-3 || std::abs(z - 1.8) < 1e-3) continue;  // kinks at the edges
    outside += (z < 1.0 || z > 1.8) ? 1 : 0;
    Values x;
    x.insert(X(0), Pose3(randomRotation(rng), Vec3(randomVec(rng, 3.0).x(), randomVec(rng, 3.0).y(), z)));
    EXPECT_TRUE(testing::jacobiansMatch(HeightBandFactor(X(0), 1.0, 1.8, 0.2), x, 1e-6)) << "z " << z;
  }
  EXPECT_GT(outside, 100);
  // Zero rotation, above the band: dr/drho = e_z^T / sigma.
  Values x;
  x.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 3)));
  Residual r;
  Jacobians H;
  HeightBandFactor(X(0), 1.0, 1.8, 0.2).evaluate(x, r, &H);
  Eigen::Matrix<double, 1, 6> expected;
  expected << 0, 0, 0, 0, 0, 5;
  EXPECT_LE((H[0] - expected).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(HeightBandFactor, EqualBoundsAndInvalidArguments) {
  const HeightBandFactor eq(X(0), 1.5, 1.5, 0.5);
  Values x;
  x.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 2.0)));
  EXPECT_NEAR(eq.error(x), 0.5, 1e-12);
  // A plain prior on z: its information stays at its own centre (the hold).
  Values at_centre;
  at_centre.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 1.5)));
  Residual r;
  Jacobians H;
  eq.evaluate(at_centre, r, &H);
  EXPECT_EQ(r(0), 0.0);
  EXPECT_DOUBLE_EQ(H[0](0, 5), 2.0);  // 1 / sigma
  EXPECT_TRUE(testing::jacobiansMatch(eq, at_centre, 1e-6));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(HeightBandFactor(X(0), 2.0, 1.0, 0.1), std::invalid_argument);
  EXPECT_THROW(HeightBandFactor(X(0), 1.0, 2.0, 0.0), std::invalid_argument);
  EXPECT_THROW(HeightBandFactor(X(0), 1.0, 2.0, -1.0), std::invalid_argument);
  EXPECT_THROW(HeightBandFactor(X(0), nan, 2.0, 0.1), std::invalid_argument);
  EXPECT_THROW(HeightBandFactor(X(0), 1.0, nan, 0.1), std::invalid_argument);
}

TEST(HeightBandFactor, RobustLossPropagates) {
  Values x;
  x.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 2.2)));  // r = 4
  EXPECT_NEAR(HeightBandFactor(X(0), 1.0, 1.8, 0.1).error(x), 8.0, 1e-9);
  EXPECT_NEAR(HeightBandFactor(X(0), 1.0, 1.8, 0.1, std::make_shared<HuberLoss>(1.0)).error(x), 3.5, 1e-9);
}

}  // namespace
}  // namespace rilo
