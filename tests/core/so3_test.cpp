#include <gtest/gtest.h>

#include <random>

#include "math/pose3.h"
#include "math/so3.h"
#include "support/random_states.h"

namespace rilo {
namespace {

using testing::randomVec;

TEST(So3, ExpLogRoundTripAcrossAngles) {
  std::mt19937 rng(1);
  for (double scale : {1e-9, 1e-6, 1e-3, 0.3, 1.0, 2.5}) {
    for (int i = 0; i < 50; ++i) {
      Vec3 phi = randomVec(rng, scale);
      if (phi.norm() > 3.1) phi *= 3.1 / phi.norm();
      const Mat3 R = so3::exp(phi);
      EXPECT_NEAR((R.transpose() * R - Mat3::Identity()).norm(), 0.0, 1e-12);
      EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
      EXPECT_LE((so3::log(R) - phi).norm(), 1e-10 * std::max(1.0, phi.norm())) << "scale " << scale;
    }
  }
}

TEST(So3, LogNearPi) {
  const Vec3 axis = Vec3(1, 2, -0.5).normalized();
  for (double a : {M_PI - 1e-3, M_PI - 1e-7, M_PI}) {
    const Vec3 phi = so3::log(so3::exp(a * axis));
    EXPECT_NEAR(phi.norm(), a, 1e-6);
    EXPECT_NEAR(std::abs(phi.normalized().dot(axis)), 1.0, 1e-6);
  }
}

TEST(So3, RightJacobianMatchesFiniteDifference) {
  std::mt19937 rng(2);
  for (double scale : {0.0, 1e-7, 0.5, 1.5}) {
    const Vec3 phi = randomVec(rng, scale);
    const Mat3 Jr = so3::rightJacobian(phi);
    const Mat3 Jr_inv = so3::rightJacobianInverse(phi);
    EXPECT_LE((Jr * Jr_inv - Mat3::Identity()).norm(), 1e-10);
    // Exp(phi + d) ~= Exp(phi) Exp(Jr d): column-wise central difference.
    const double h = 1e-6;
    Mat3 Jn;
    for (int i = 0; i < 3; ++i) {
      Vec3 d = Vec3::Zero();
      d(i) = h;
      const Mat3 R0T = so3::exp(phi).transpose();
      Jn.col(i) = (so3::log(R0T * so3::exp(phi + d)) - so3::log(R0T * so3::exp(phi - d))) / (2 * h);
    }
    EXPECT_LE((Jn - Jr).cwiseAbs().maxCoeff(), 1e-8) << "phi " << phi.transpose();
  }
}

TEST(Pose3, LocalIsInverseOfRetract) {
  std::mt19937 rng(3);
  for (int i = 0; i < 20; ++i) {
    const Pose3 T(so3::exp(randomVec(rng, 1.0)), randomVec(rng, 5.0));
    Vec6 xi;
    xi << randomVec(rng, 0.5), randomVec(rng, 2.0);
    EXPECT_LE((T.local(T.retract(xi)) - xi).norm(), 1e-10);
  }
}

TEST(Pose3, ExpmapLogmapRoundTripAndMatchConstantTwistIntegration) {
  std::mt19937 rng(4);
  for (double scale : {0.0, 1e-8, 0.3, 1.5}) {
    Vec6 xi;
    xi << randomVec(rng, scale), randomVec(rng, 2.0);
    if (xi.head<3>().norm() > 3.0) xi.head<3>() *= 3.0 / xi.head<3>().norm();
    const Pose3 T = Pose3::expmap(xi);
    EXPECT_LE((Pose3::logmap(T) - xi).norm(), 1e-9 * std::max(1.0, xi.norm()));
    // exp of a twist = integrating body velocity [omega; v] for unit time.
    Pose3 Tn;
    const int n = 20000;
    for (int k = 0; k < n; ++k) {
      Tn = Tn.compose(Pose3(so3::exp(xi.head<3>() / n), xi.tail<3>() / n));
    }
    EXPECT_LE((Tn.p - T.p).norm(), 1e-3) << "scale " << scale;
    EXPECT_LE(so3::log(Tn.R.transpose() * T.R).norm(), 1e-9);
  }
  const Pose3 A(so3::exp(Vec3(0.3, -0.2, 1.0)), Vec3(1, 2, 3));
  const Pose3 I = A.compose(A.inverse());
  EXPECT_LE((I.R - Mat3::Identity()).norm(), 1e-12);
  EXPECT_LE(I.p.norm(), 1e-12);
}

}  // namespace
}  // namespace rilo
