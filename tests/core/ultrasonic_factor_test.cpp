#include "estimation/factors/ultrasonic_factor.h"

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

Values poseAndAnchor(const Pose3& T_w_b, const Vec3& p_w_anchor) {
  Values v;
  v.insert(X(0), T_w_b);
  v.insert(L(7), p_w_anchor);
  return v;
}

TEST(UltrasonicFactor, ResidualAtKnownConfiguration) {
  // Receiver at (0,0,1), anchor at (0,3,5): d = (0,-3,-4), range 5, height diff -4.
  const Pose3 T_w_b(Mat3::Identity(), Vec3(0, 0, 1));
  const Vec3 p_w_anchor(0, 3, 5);
  const UltrasonicElevation elev{-3.9, 0.05};
  const UltrasonicFactor f2(X(0), p_w_anchor, 4.9, 0.1, Vec3::Zero(), elev);
  Values x;
  x.insert(X(0), T_w_b);
  EXPECT_EQ(f2.dim(), 2);
  EXPECT_NEAR(f2.predictedRange(x), 5.0, 1e-12);
  EXPECT_NEAR(f2.predictedHeightDifference(x), -4.0, 1e-12);
  Residual r;
  f2.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 2);
  EXPECT_NEAR(r(0), -1.0, 1e-10);  // measured shorter
  EXPECT_NEAR(r(1), -2.0, 1e-10);  // (-4 - (-3.9)) / 0.05
  EXPECT_NEAR(f2.error(x), 0.5 * (1.0 + 4.0), 1e-9);

  const UltrasonicFactor f1(X(0), p_w_anchor, 5.2, 0.1, Vec3::Zero());
  EXPECT_EQ(f1.dim(), 1);
  f1.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 1);
  EXPECT_NEAR(r(0), 2.0, 1e-10);  // measured longer => positive

  // Lever arm through a 180 deg yaw: (0.5,0,0) in body is (-0.5,0,0) in world.
  const Pose3 T_yaw(so3::exp(Vec3(0, 0, M_PI)), Vec3(0.5, 0, 1));
  Values xy;
  xy.insert(X(0), T_yaw);
  EXPECT_NEAR(UltrasonicFactor(X(0), p_w_anchor, 5.0, 0.1, Vec3(0.5, 0, 0)).predictedRange(xy), 5.0, 1e-12);
}

TEST(UltrasonicFactor, AnchorVariableMatchesConstant) {
  std::mt19937 rng(30);
  const Pose3 T_w_b = randomPose(rng, 3.0);
  const Vec3 p_w_anchor = randomVec(rng, 4.0);
  const Vec3 lever(0.05, -0.1, 0.2);
  const UltrasonicElevation elev{-1.5, 0.1};
  const UltrasonicFactor fv(X(0), L(7), 3.0, 0.02, lever, elev);
  const UltrasonicFactor fc(X(0), p_w_anchor, 3.0, 0.02, lever, elev);
  const Values x = poseAndAnchor(T_w_b, p_w_anchor);
  Residual rv, rc;
  fv.evaluate(x, rv, nullptr);
  fc.evaluate(x, rc, nullptr);
  EXPECT_NEAR((rv - rc).norm(), 0.0, 1e-12);
  EXPECT_TRUE(fv.anchorIsVariable());
  EXPECT_EQ(fv.anchorKey(), L(7));
  EXPECT_FALSE(fc.anchorIsVariable());
  EXPECT_THROW(static_cast<void>(fc.anchorKey()), std::logic_error);
  EXPECT_EQ(fc.anchorPosition(x), p_w_anchor);
  ASSERT_TRUE(fv.elevation().has_value());
  EXPECT_DOUBLE_EQ(fv.elevation()->delta_h_m, -1.5);
  EXPECT_DOUBLE_EQ(fv.sigmaRange(), 0.02);
  EXPECT_DOUBLE_EQ(fv.measuredRange(), 3.0);
  EXPECT_EQ(fv.leverArm(), lever);
}

TEST(UltrasonicFactor, JacobiansMatchAtRandomStates) {
  std::mt19937 rng(31);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 lever = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 6.0);
    const double z = (T_w_b.transformFrom(lever) - p_w_anchor).norm() + randomVec(rng, 0.1).x();
    const UltrasonicElevation elev{randomVec(rng, 2.0).x(), 0.05};
    const Values x = poseAndAnchor(T_w_b, p_w_anchor);
    for (bool with_elevation : {false, true}) {
      const std::optional<UltrasonicElevation> e = with_elevation ? std::optional(elev) : std::nullopt;
      EXPECT_TRUE(testing::jacobiansMatch(UltrasonicFactor(X(0), L(7), z, 0.03, lever, e), x, 1e-6)) << i;
      EXPECT_TRUE(testing::jacobiansMatch(UltrasonicFactor(X(0), p_w_anchor, z, 0.03, lever, e), x, 1e-6)) << i;
    }
  }
}

TEST(UltrasonicFactor, JacobiansMatchAtZeroRotation) {
  std::mt19937 rng(32);
  for (int i = 0; i < 20; ++i) {
    const Pose3 T_w_b(Mat3::Identity(), randomVec(rng, 3.0));
    const Values x = poseAndAnchor(T_w_b, randomVec(rng, 5.0));
    const UltrasonicFactor f(X(0), L(7), 2.0, 0.03, randomVec(rng, 0.3), UltrasonicElevation{-1.0, 0.1});
    EXPECT_TRUE(testing::jacobiansMatch(f, x, 1e-6));
  }
}

TEST(UltrasonicFactor, JacobiansMatchNearAnchorAndFiniteAtIt) {
  std::mt19937 rng(33);
  for (int i = 0; i < 50; ++i) {
    const Pose3 T_w_b = randomPose(rng, 2.0);
    const Vec3 lever = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = T_w_b.transformFrom(lever) + 1e-4 * randomVec(rng, 1.0).normalized();
    const UltrasonicFactor f(X(0), L(7), 0.1, 0.03, lever, UltrasonicElevation{0.0, 0.1});
    EXPECT_TRUE(testing::jacobiansMatch(f, poseAndAnchor(T_w_b, p_w_anchor), 1e-6, 1e-8)) << i;
  }
  const Pose3 T_w_b(so3::exp(Vec3(-2.5, 0.3, 0.7)), Vec3(1, 2, 0.5));
  const Vec3 lever(0.1, 0.0, -0.2);
  const UltrasonicFactor f(X(0), L(7), 0.1, 0.03, lever, UltrasonicElevation{0.0, 0.1});
  Residual r;
  Jacobians H;
  f.evaluate(poseAndAnchor(T_w_b, T_w_b.transformFrom(lever)), r, &H);
  EXPECT_TRUE(r.allFinite());
  EXPECT_TRUE(H[0].allFinite());
  EXPECT_TRUE(H[1].allFinite());
  EXPECT_NEAR(r(1), 0.0, 1e-12);
}

TEST(UltrasonicFactor, RobustLossRules) {
  const Pose3 T_w_b(Mat3::Identity(), Vec3(0, 0, 1));
  const Vec3 p_w_anchor(0, 3, 5);
  Values x;
  x.insert(X(0), T_w_b);
  const UltrasonicElevation elev{-3.9, 0.05};
  auto huber = std::make_shared<HuberLoss>(1.0);
  auto asym = std::make_shared<TestAsymmetric>();

  // 1-dim: any loss, signed residual.
  EXPECT_NEAR(UltrasonicFactor(X(0), p_w_anchor, 5.4, 0.1, Vec3::Zero(), std::nullopt, huber).error(x), 3.5, 1e-9);
  EXPECT_NEAR(UltrasonicFactor(X(0), p_w_anchor, 5.2, 0.1, Vec3::Zero(), std::nullopt, asym).error(x), 0.5, 1e-9);
  EXPECT_NEAR(UltrasonicFactor(X(0), p_w_anchor, 4.8, 0.1, Vec3::Zero(), std::nullopt, asym).error(x), 2.0, 1e-9);

  // 2-dim: symmetric loss on |r| (r = (-1, -2), |r| = sqrt 5).
  const UltrasonicFactor plain(X(0), p_w_anchor, 4.9, 0.1, Vec3::Zero(), elev);
  const UltrasonicFactor robust(X(0), p_w_anchor, 4.9, 0.1, Vec3::Zero(), elev, huber);
  EXPECT_NEAR(plain.error(x), 2.5, 1e-9);
  EXPECT_NEAR(robust.error(x), std::sqrt(5.0) - 0.5, 1e-9);

  // 2-dim with an asymmetric loss: rejected, naming the loss.
  EXPECT_THROW(UltrasonicFactor(X(0), p_w_anchor, 4.9, 0.1, Vec3::Zero(), elev, asym), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(7), 4.9, 0.1, Vec3::Zero(), elev, asym), std::invalid_argument);
  try {
    UltrasonicFactor(X(0), L(7), 4.9, 0.1, Vec3::Zero(), elev, asym);
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("test_asymmetric"), std::string::npos) << e.what();
  }
}

TEST(UltrasonicFactor, ARangeAfterItsStateSeesTheReceiverMovedOnByTheStatesVelocity) {
  const Pose3 T_w_b(so3::exp(Vec3(0, 0, 0.3)), Vec3(1, 2, 1.0));
  const Vec3 p_b_us(0.0, 0.05, 0.2);
  const Vec3 v_w(1.5, 0.0, 0.2);
  const Vec3 p_w_anchor(4, 2, 2.5);
  const double dt_s = 0.04;
  const Vec3 d_w = T_w_b.transformFrom(p_b_us) + dt_s * v_w - p_w_anchor;
  const UltrasonicElevation elevation{d_w.z(), 0.05};
  const UltrasonicFactor f(X(0), L(7), d_w.norm(), 0.02, p_b_us, elevation, nullptr, RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(f.keys().size(), 3u);
  EXPECT_EQ(f.keys()[2], V(0));
  EXPECT_TRUE(f.hasTimeOffset());
  EXPECT_DOUBLE_EQ(f.timeOffset(), dt_s);
  Values x = poseAndAnchor(T_w_b, p_w_anchor);
  x.insert(V(0), v_w);
  EXPECT_NEAR(f.predictedRange(x), d_w.norm(), 1e-12);
  EXPECT_NEAR(f.predictedHeightDifference(x), d_w.z(), 1e-12);
  Residual r;
  f.evaluate(x, r, nullptr);
  EXPECT_NEAR(r.norm(), 0.0, 1e-10);
  const UltrasonicFactor fc(X(0), p_w_anchor, d_w.norm(), 0.02, p_b_us, std::nullopt, nullptr,
                            RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(fc.keys().size(), 2u);
  EXPECT_EQ(fc.keys()[1], V(0));
  EXPECT_NEAR(fc.predictedRange(x), d_w.norm(), 1e-12);
  const UltrasonicFactor plain(X(0), p_w_anchor, d_w.norm(), 0.02, p_b_us);
  EXPECT_FALSE(plain.hasTimeOffset());
  EXPECT_GT(std::abs(plain.predictedRange(x) - d_w.norm()), 0.03) << "6 cm walked, mostly towards the anchor";
}

TEST(UltrasonicFactor, JacobiansMatchWithATimeOffset) {
  std::mt19937 rng(16);
  std::uniform_real_distribution<double> offset(-0.05, 0.05);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_us = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 6.0);
    const Vec3 v_w = randomVec(rng, 2.0);
    const RangeTimeOffset dt{V(0), offset(rng)};
    const double z = (T_w_b.transformFrom(p_b_us) - p_w_anchor).norm() + randomVec(rng, 0.3).x();
    std::optional<UltrasonicElevation> elevation;
    if (i % 2 == 1) elevation = UltrasonicElevation{randomVec(rng, 2.0).z(), 0.05};
    const UltrasonicFactor fv(X(0), L(7), z, 0.02, p_b_us, elevation, nullptr, dt);
    const UltrasonicFactor fc(X(0), p_w_anchor, z, 0.02, p_b_us, elevation, nullptr, dt);
    Values x = poseAndAnchor(T_w_b, p_w_anchor);
    x.insert(V(0), v_w);
    EXPECT_TRUE(testing::jacobiansMatch(fv, x, 1e-6)) << "sample " << i;
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(UltrasonicFactor, ABadTimeOffsetThrows) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec3 z = Vec3::Zero();
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.1, z, std::nullopt, nullptr, RangeTimeOffset{V(0), nan}),
               std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.1, z, std::nullopt, nullptr, RangeTimeOffset{L(1), 0.01}),
               std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), Vec3(0, 0, 3), 1.0, 0.1, z, std::nullopt, nullptr, RangeTimeOffset{X(0), 0.01}),
               std::invalid_argument);
}

TEST(UltrasonicFactor, InvalidArgumentsThrow) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const Vec3 z = Vec3::Zero();
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.0, z), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, -0.1, z), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), nan, 0.1, z), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.1, Vec3(nan, 0, 0)), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), X(0), 1.0, 0.1, z), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.1, z, UltrasonicElevation{0.0, 0.0}), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), L(1), 1.0, 0.1, z, UltrasonicElevation{nan, 0.1}), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), Vec3(0, 0, nan), 1.0, 0.1, z), std::invalid_argument);
  EXPECT_THROW(UltrasonicFactor(X(0), Vec3(0, 0, 0), 1.0, 0.1, z, UltrasonicElevation{1.0, -1.0}),
               std::invalid_argument);
}

}  // namespace
}  // namespace rilo
