#include "estimation/factors/tdoa_factor.h"

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

using sym::L;
using sym::V;
using sym::X;
using testing::TestAsymmetric;
using testing::randomPose;
using testing::randomVec;

Values poseAndAnchors(const Pose3& T_w_b, const Vec3& p_w_a, const Vec3& p_w_b) {
  Values v;
  v.insert(X(0), T_w_b);
  v.insert(L(1), p_w_a);
  v.insert(L(2), p_w_b);
  return v;
}

TEST(TdoaFactor, ResidualAtKnownConfiguration) {
  // Tag at the origin: |A_a| = 5, |A_b| = 10, h = 10 - 5 = 5.
  const Vec3 p_w_a(3, 4, 0), p_w_b(6, 8, 0);
  const Pose3 T_w_b(so3::exp(Vec3(0.4, 0.2, -1.0)), Vec3(0, 0, 0));
  const TdoaFactor fc(X(0), p_w_a, p_w_b, 5.3, 0.15, Vec3::Zero());
  Values x;
  x.insert(X(0), T_w_b);
  EXPECT_NEAR(fc.predictedDifference(x), 5.0, 1e-12);
  Residual r;
  fc.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 1);
  EXPECT_NEAR(r(0), 2.0, 1e-10);

  const TdoaFactor fv(X(0), L(1), L(2), 5.3, 0.15, Vec3::Zero());
  fv.evaluate(poseAndAnchors(T_w_b, p_w_a, p_w_b), r, nullptr);
  EXPECT_NEAR(r(0), 2.0, 1e-10);

  // Lever arm: body at (0,0,-1), identity rotation, tag 1 m above = origin again.
  const Pose3 T_low(Mat3::Identity(), Vec3(0, 0, -1));
  Values xl;
  xl.insert(X(0), T_low);
  EXPECT_NEAR(TdoaFactor(X(0), p_w_a, p_w_b, 5.0, 0.1, Vec3(0, 0, 1)).predictedDifference(xl), 5.0, 1e-12);
}

TEST(TdoaFactor, SignMeansLateSignalFromB) {
  const Vec3 p_w_a(3, 4, 0), p_w_b(6, 8, 0);  // h = 5 at the origin
  Values x;
  x.insert(X(0), Pose3());
  Residual r;
  // NLOS on b: b's path reads longer, diff larger than predicted => r > 0.
  TdoaFactor(X(0), p_w_a, p_w_b, 5.0 + 0.4, 0.1, Vec3::Zero()).evaluate(x, r, nullptr);
  EXPECT_NEAR(r(0), 4.0, 1e-10);
  // NLOS on a: a's path reads longer, diff smaller => r < 0.
  TdoaFactor(X(0), p_w_a, p_w_b, 5.0 - 0.4, 0.1, Vec3::Zero()).evaluate(x, r, nullptr);
  EXPECT_NEAR(r(0), -4.0, 1e-10);
}

TEST(TdoaFactor, Accessors) {
  const TdoaFactor fv(X(4), L(1), L(2), 0.7, 0.05, Vec3(0, 0, 0.1));
  EXPECT_TRUE(fv.anchorsAreVariables());
  EXPECT_EQ(fv.poseKey(), X(4));
  EXPECT_EQ(fv.anchorAKey(), L(1));
  EXPECT_EQ(fv.anchorBKey(), L(2));
  EXPECT_DOUBLE_EQ(fv.measuredDifference(), 0.7);
  EXPECT_DOUBLE_EQ(fv.sigma(), 0.05);
  EXPECT_EQ(fv.leverArm(), Vec3(0, 0, 0.1));
  ASSERT_EQ(fv.keys().size(), 3u);

  const TdoaFactor fc(X(4), Vec3(1, 0, 0), Vec3(0, 1, 0), 0.7, 0.05, Vec3::Zero());
  EXPECT_FALSE(fc.anchorsAreVariables());
  EXPECT_THROW(static_cast<void>(fc.anchorAKey()), std::logic_error);
  EXPECT_THROW(static_cast<void>(fc.anchorBKey()), std::logic_error);
  Values x;
  EXPECT_EQ(fc.anchorAPosition(x), Vec3(1, 0, 0));
  EXPECT_EQ(fc.anchorBPosition(x), Vec3(0, 1, 0));
  ASSERT_EQ(fc.keys().size(), 1u);
}

TEST(TdoaFactor, JacobiansMatchAtRandomStates) {
  std::mt19937 rng(21);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_a = randomVec(rng, 6.0), p_w_b = randomVec(rng, 6.0);
    const Vec3 p_w_tag = T_w_b.transformFrom(p_b_tag);
    const double z = (p_w_tag - p_w_b).norm() - (p_w_tag - p_w_a).norm() + randomVec(rng, 0.3).x();
    const TdoaFactor fv(X(0), L(1), L(2), z, 0.1, p_b_tag);
    EXPECT_TRUE(testing::jacobiansMatch(fv, poseAndAnchors(T_w_b, p_w_a, p_w_b), 1e-6)) << "sample " << i;
    const TdoaFactor fc(X(0), p_w_a, p_w_b, z, 0.1, p_b_tag);
    Values x;
    x.insert(X(0), T_w_b);
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(TdoaFactor, JacobiansMatchAtZeroRotation) {
  std::mt19937 rng(22);
  for (int i = 0; i < 20; ++i) {
    const Pose3 T_w_b(Mat3::Identity(), randomVec(rng, 3.0));
    const TdoaFactor fv(X(0), L(1), L(2), 0.5, 0.1, randomVec(rng, 0.3));
    EXPECT_TRUE(testing::jacobiansMatch(fv, poseAndAnchors(T_w_b, randomVec(rng, 5.0), randomVec(rng, 5.0)), 1e-6));
  }
}

TEST(TdoaFactor, JacobiansMatchNearEitherAnchor) {
  std::mt19937 rng(23);
  for (int i = 0; i < 50; ++i) {
    const Pose3 T_w_b = randomPose(rng, 2.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 near = T_w_b.transformFrom(p_b_tag) + 1e-4 * randomVec(rng, 1.0).normalized();
    const Vec3 far = randomVec(rng, 5.0);
    for (bool near_is_a : {true, false}) {
      const Vec3& p_w_a = near_is_a ? near : far;
      const Vec3& p_w_b = near_is_a ? far : near;
      // sigma 1: the far range's rounding (~1e-15 m over a 2e-8 step) stays well below the tolerance.
      const TdoaFactor fv(X(0), L(1), L(2), 1.0, 1.0, p_b_tag);
      const Values x = poseAndAnchors(T_w_b, p_w_a, p_w_b);
      EXPECT_TRUE(testing::jacobiansMatch(fv, x, 1e-6, 1e-8)) << "sample " << i << " near a " << near_is_a;
      const TdoaFactor fc(X(0), p_w_a, p_w_b, 1.0, 1.0, p_b_tag);
      EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6, 1e-8)) << "sample " << i << " near a " << near_is_a;
    }
  }
}

TEST(TdoaFactor, ExactlyAtAnchorIsFinite) {
  const Pose3 T_w_b(so3::exp(Vec3(2.0, -0.5, 1.0)), Vec3(1, 1, 1));
  const Vec3 p_b_tag(0.1, 0.2, 0.3);
  const Vec3 on_tag = T_w_b.transformFrom(p_b_tag);
  const Vec3 far(4, -3, 2);
  for (bool on_a : {true, false}) {
    const TdoaFactor fv(X(0), L(1), L(2), 0.0, 0.1, p_b_tag);
    const Values x = on_a ? poseAndAnchors(T_w_b, on_tag, far) : poseAndAnchors(T_w_b, far, on_tag);
    Residual r;
    Jacobians H;
    fv.evaluate(x, r, &H);
    EXPECT_TRUE(r.allFinite());
    for (int k = 0; k < 3; ++k) EXPECT_TRUE(H[static_cast<std::size_t>(k)].allFinite()) << k;
    // The on-tag anchor's block uses the fixed direction (0, 0, -1).
    const Eigen::RowVector3d expected = on_a ? Eigen::RowVector3d(0, 0, 10) : Eigen::RowVector3d(0, 0, -10);
    EXPECT_NEAR((H[on_a ? 1 : 2] - expected).norm(), 0.0, 1e-12);
  }
}

TEST(TdoaFactor, RobustLossPropagates) {
  const Vec3 p_w_a(3, 4, 0), p_w_b(6, 8, 0);
  Values x;
  x.insert(X(0), Pose3());
  const TdoaFactor plain(X(0), p_w_a, p_w_b, 5.4, 0.1, Vec3::Zero());
  const TdoaFactor huber(X(0), p_w_a, p_w_b, 5.4, 0.1, Vec3::Zero(), std::make_shared<HuberLoss>(1.0));
  EXPECT_NEAR(plain.error(x), 8.0, 1e-9);
  EXPECT_NEAR(huber.error(x), 3.5, 1e-9);
  Residual r;
  Jacobians H;
  EXPECT_NEAR(huber.linearize(x, r, H), 0.25, 1e-12);
  EXPECT_NEAR(r(0), 2.0, 1e-10);

  // Asymmetric losses are accepted and see the sign (NLOS on b vs on a).
  auto asym = std::make_shared<TestAsymmetric>();
  EXPECT_NEAR(TdoaFactor(X(0), p_w_a, p_w_b, 5.2, 0.1, Vec3::Zero(), asym).error(x), 0.5, 1e-9);
  EXPECT_NEAR(TdoaFactor(X(0), p_w_a, p_w_b, 4.8, 0.1, Vec3::Zero(), asym).error(x), 2.0, 1e-9);
}

TEST(TdoaFactor, ARowAfterItsStateSeesTheTagMovedOnByTheStatesVelocity) {
  // Walking at 1.5 m/s along x; the row is measured 40 ms after the state.
  const Pose3 T_w_b(so3::exp(Vec3(0, 0, 0.3)), Vec3(1, 2, 1.5));
  const Vec3 p_b_tag(0.06, 0.0, 0.1);
  const Vec3 v_w(1.5, 0.0, 0.0);
  const Vec3 p_w_a(-4, 2, 2.5), p_w_b(8, 3, 2.5);  // behind and ahead
  const double dt_s = 0.04;
  const Vec3 p_w_tag = T_w_b.transformFrom(p_b_tag) + dt_s * v_w;
  const double truth_m = (p_w_tag - p_w_b).norm() - (p_w_tag - p_w_a).norm();
  const TdoaFactor f(X(0), L(1), L(2), truth_m, 0.1, p_b_tag, nullptr, RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(f.keys().size(), 4u);
  EXPECT_EQ(f.keys()[3], V(0));
  EXPECT_TRUE(f.hasTimeOffset());
  EXPECT_DOUBLE_EQ(f.timeOffset(), dt_s);
  Values x = poseAndAnchors(T_w_b, p_w_a, p_w_b);
  x.insert(V(0), v_w);
  EXPECT_NEAR(f.predictedDifference(x), truth_m, 1e-12);
  Residual r;
  Jacobians H;
  f.evaluate(x, r, &H);
  EXPECT_NEAR(r(0), 0.0, 1e-10);
  // The velocity Jacobian is dt times the position's.
  EXPECT_TRUE(H[3].isApprox(dt_s * H[0].rightCols<3>() * T_w_b.R.transpose(), 1e-12));
  // Without the offset the row misses by the 6 cm walked, counted twice
  // (away from a, towards b): predicted about 0.12 m too long.
  const TdoaFactor plain(X(0), L(1), L(2), truth_m, 0.1, p_b_tag);
  EXPECT_FALSE(plain.hasTimeOffset());
  EXPECT_EQ(plain.timeOffset(), 0.0);
  EXPECT_NEAR(plain.predictedDifference(x) - truth_m, 0.12, 0.01);

  // Constant anchors: keys {pose, velocity}.
  const TdoaFactor fc(X(0), p_w_a, p_w_b, truth_m, 0.1, p_b_tag, nullptr, RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(fc.keys().size(), 2u);
  EXPECT_EQ(fc.keys()[1], V(0));
  EXPECT_NEAR(fc.predictedDifference(x), truth_m, 1e-12);
}

TEST(TdoaFactor, JacobiansMatchWithATimeOffset) {
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> offset(-0.05, 0.05);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_a = randomVec(rng, 6.0), p_w_b = randomVec(rng, 6.0);
    const Vec3 v_w = randomVec(rng, 2.0);
    const RangeTimeOffset dt{V(0), offset(rng)};
    const double z = randomVec(rng, 4.0).x();
    const TdoaFactor fv(X(0), L(1), L(2), z, 0.1, p_b_tag, nullptr, dt);
    const TdoaFactor fc(X(0), p_w_a, p_w_b, z, 0.1, p_b_tag, nullptr, dt);
    Values x = poseAndAnchors(T_w_b, p_w_a, p_w_b);
    x.insert(V(0), v_w);
    EXPECT_TRUE(testing::jacobiansMatch(fv, x, 1e-6)) << "sample " << i;
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(TdoaFactor, ABadTimeOffsetThrows) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec3 z = Vec3::Zero();
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), 0.5, 0.1, z, nullptr, RangeTimeOffset{V(0), nan}), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), Vec3(1, 2, 3), Vec3(0, 0, 0), 0.5, 0.1, z, nullptr, RangeTimeOffset{V(0), nan}),
               std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), 0.5, 0.1, z, nullptr, RangeTimeOffset{L(2), 0.01}), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), Vec3(1, 2, 3), Vec3(0, 0, 0), 0.5, 0.1, z, nullptr, RangeTimeOffset{X(0), 0.01}),
               std::invalid_argument);
}

TEST(TdoaFactor, InvalidArgumentsThrow) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec3 z = Vec3::Zero();
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), 0.5, 0.0, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), 0.5, -1.0, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), nan, 0.1, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(2), 0.5, 0.1, Vec3(0, nan, 0)), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), L(1), L(1), 0.5, 0.1, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(L(1), L(1), L(2), 0.5, 0.1, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), Vec3(1, 2, 3), Vec3(1, 2, 3), 0.5, 0.1, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), Vec3(1, 2, 3), Vec3(1, 2, nan), 0.5, 0.1, z), std::invalid_argument);
  EXPECT_THROW(TdoaFactor(X(0), Vec3(1, 2, 3), Vec3(0, 0, 0), 0.5, 0.0, z), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
