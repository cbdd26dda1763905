#include "estimation/factors/range_factor.h"

#include <gtest/gtest.h>

#include <cmath>
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
  v.insert(L(3), p_w_anchor);
  return v;
}

TEST(RangeFactor, ResidualAtKnownConfiguration) {
  // Body rotated 90 deg about z: lever arm (1,0,0) points along world y.
  const Pose3 T_w_b(so3::exp(Vec3(0, 0, M_PI / 2)), Vec3(0, 0, 0));
  const Vec3 p_b_tag(1, 0, 0);
  const Vec3 p_w_anchor(3, 5, 0);  // tag at (0,1,0): d = (-3,-4,0), h = 5
  const RangeFactor f(X(0), p_w_anchor, 5.2, 0.1, p_b_tag);
  Values x;
  x.insert(X(0), T_w_b);
  EXPECT_NEAR(f.predictedRange(x), 5.0, 1e-12);
  Residual r;
  f.evaluate(x, r, nullptr);
  ASSERT_EQ(r.size(), 1);
  EXPECT_NEAR(r(0), 2.0, 1e-10);
  EXPECT_NEAR(f.error(x), 2.0, 1e-9);  // r^2/2

  // Same geometry with the anchor as a variable.
  const RangeFactor fv(X(0), L(3), 5.2, 0.1, p_b_tag);
  const Values xv = poseAndAnchor(T_w_b, p_w_anchor);
  fv.evaluate(xv, r, nullptr);
  EXPECT_NEAR(r(0), 2.0, 1e-10);
}

TEST(RangeFactor, MeasuredLongerGivesPositiveResidual) {
  const Pose3 T_w_b(Mat3::Identity(), Vec3(1, 2, 1));
  const Vec3 p_w_anchor(4, 6, 1);  // h = 5
  Values x;
  x.insert(X(0), T_w_b);
  Residual r;
  RangeFactor(X(0), p_w_anchor, 5.3, 0.1, Vec3::Zero()).evaluate(x, r, nullptr);
  EXPECT_GT(r(0), 0.0);  // NLOS side
  EXPECT_NEAR(r(0), 3.0, 1e-10);
  RangeFactor(X(0), p_w_anchor, 4.8, 0.1, Vec3::Zero()).evaluate(x, r, nullptr);
  EXPECT_LT(r(0), 0.0);
  EXPECT_NEAR(r(0), -2.0, 1e-10);
}

TEST(RangeFactor, Accessors) {
  const Vec3 p_b_tag(0.1, -0.2, 0.3);
  const RangeFactor fv(X(1), L(2), 7.5, 0.2, p_b_tag);
  EXPECT_TRUE(fv.anchorIsVariable());
  EXPECT_EQ(fv.anchorKey(), L(2));
  EXPECT_EQ(fv.poseKey(), X(1));
  EXPECT_DOUBLE_EQ(fv.measuredRange(), 7.5);
  EXPECT_DOUBLE_EQ(fv.sigma(), 0.2);
  EXPECT_EQ(fv.leverArm(), p_b_tag);
  ASSERT_EQ(fv.keys().size(), 2u);

  const Vec3 p_w_anchor(1, 2, 3);
  const RangeFactor fc(X(1), p_w_anchor, 7.5, 0.2, p_b_tag);
  EXPECT_FALSE(fc.anchorIsVariable());
  EXPECT_THROW(static_cast<void>(fc.anchorKey()), std::logic_error);
  Values x;
  x.insert(X(1), Pose3());
  EXPECT_EQ(fc.anchorPosition(x), p_w_anchor);
  ASSERT_EQ(fc.keys().size(), 1u);
  x.insert(L(2), Vec3(4, 5, 6));
  EXPECT_EQ(fv.anchorPosition(x), Vec3(4, 5, 6));
}

TEST(RangeFactor, JacobiansMatchAtRandomStates) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> sigma_dist(0.02, 0.5);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 6.0);
    const double z = (T_w_b.transformFrom(p_b_tag) - p_w_anchor).norm() + randomVec(rng, 0.3).x();
    const double sigma = sigma_dist(rng);

    const RangeFactor fv(X(0), L(3), z, sigma, p_b_tag);
    EXPECT_TRUE(testing::jacobiansMatch(fv, poseAndAnchor(T_w_b, p_w_anchor), 1e-6)) << "sample " << i;

    const RangeFactor fc(X(0), p_w_anchor, z, sigma, p_b_tag);
    Values x;
    x.insert(X(0), T_w_b);
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(RangeFactor, JacobiansMatchAtZeroRotation) {
  std::mt19937 rng(12);
  for (int i = 0; i < 20; ++i) {
    const Pose3 T_w_b(Mat3::Identity(), randomVec(rng, 3.0));
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 5.0);
    const RangeFactor fv(X(0), L(3), 4.0, 0.1, p_b_tag);
    EXPECT_TRUE(testing::jacobiansMatch(fv, poseAndAnchor(T_w_b, p_w_anchor), 1e-6));
    const RangeFactor f0(X(0), L(3), 4.0, 0.1, Vec3::Zero());  // no lever arm: no rotation dependence
    Residual r;
    Jacobians H;
    f0.evaluate(poseAndAnchor(T_w_b, p_w_anchor), r, &H);
    EXPECT_LE(H[0].leftCols(3).cwiseAbs().maxCoeff(), 1e-15);
  }
}

TEST(RangeFactor, JacobiansMatchNearAnchor) {
  // Tag 1e-4 m from the anchor, in random directions. The norm curves on the
  // scale of 1e-4 m, so the numerical derivative needs a smaller step.
  std::mt19937 rng(13);
  for (int i = 0; i < 50; ++i) {
    const Pose3 T_w_b = randomPose(rng, 2.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = T_w_b.transformFrom(p_b_tag) + 1e-4 * randomVec(rng, 1.0).normalized();
    const RangeFactor fv(X(0), L(3), 0.05, 0.1, p_b_tag);
    const Values x = poseAndAnchor(T_w_b, p_w_anchor);
    EXPECT_NEAR(fv.predictedRange(x), 1e-4, 1e-12);
    EXPECT_TRUE(testing::jacobiansMatch(fv, x, 1e-6, 1e-8)) << "sample " << i;
    const RangeFactor fc(X(0), p_w_anchor, 0.05, 0.1, p_b_tag);
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6, 1e-8)) << "sample " << i;
  }
}

TEST(RangeFactor, ExactlyAtAnchorIsFiniteWithDocumentedDirection) {
  const Mat3 R = so3::exp(Vec3(0.3, -1.2, 2.0));
  const Vec3 p_b_tag(0.2, 0.1, -0.05);
  const Pose3 T_w_b(R, Vec3(1, 2, 3));
  const Vec3 p_w_anchor = T_w_b.transformFrom(p_b_tag);
  const RangeFactor fv(X(0), L(3), 0.5, 0.1, p_b_tag);
  const Values x = poseAndAnchor(T_w_b, p_w_anchor);
  Residual r;
  Jacobians H;
  fv.evaluate(x, r, &H);
  ASSERT_TRUE(r.allFinite());
  EXPECT_NEAR(r(0), 5.0, 1e-9);
  ASSERT_TRUE(H[0].allFinite());
  ASSERT_TRUE(H[1].allFinite());
  // dr/dp_anchor = u^T / sigma with u = (0, 0, -1).
  EXPECT_NEAR((H[1] - Eigen::RowVector3d(0, 0, -10)).norm(), 0.0, 1e-12);
  // dr/drho = -u^T R / sigma.
  EXPECT_NEAR((H[0].rightCols(3) - Eigen::RowVector3d(0, 0, 10) * R).norm(), 0.0, 1e-12);

  const RangeAndDirection rd = rangeAndDirection(Vec3::Zero());
  EXPECT_EQ(rd.range_m, 0.0);
  EXPECT_EQ(rd.u_w, Vec3(0, 0, -1));
  const RangeAndDirection tiny = rangeAndDirection(Vec3(1e-300, 0, 0));  // squaredNorm underflows
  EXPECT_TRUE(tiny.u_w.allFinite());
  EXPECT_NEAR(tiny.u_w.norm(), 1.0, 1e-15);
}

TEST(RangeFactor, RobustLossPropagatesWithSign) {
  const Pose3 T_w_b(Mat3::Identity(), Vec3::Zero());
  const Vec3 p_w_anchor(3, 4, 0);  // h = 5
  Values x;
  x.insert(X(0), T_w_b);

  const RangeFactor plain(X(0), p_w_anchor, 5.4, 0.1, Vec3::Zero());
  const RangeFactor huber(X(0), p_w_anchor, 5.4, 0.1, Vec3::Zero(), std::make_shared<HuberLoss>(1.0));
  EXPECT_NEAR(plain.error(x), 8.0, 1e-9);        // r = 4
  EXPECT_NEAR(huber.error(x), 1.0 * (4.0 - 0.5), 1e-9);
  EXPECT_NE(plain.error(x), huber.error(x));

  // IRLS: r and H scaled by sqrt(w), w = 1/4 at r = 4.
  Residual r_plain, r_huber;
  Jacobians H_plain, H_huber;
  EXPECT_DOUBLE_EQ(plain.linearize(x, r_plain, H_plain), 1.0);
  const double w = huber.linearize(x, r_huber, H_huber);
  EXPECT_NEAR(w, 0.25, 1e-12);
  EXPECT_NEAR(r_huber(0), 0.5 * r_plain(0), 1e-12);
  EXPECT_NEAR((H_huber[0] - 0.5 * H_plain[0]).norm(), 0.0, 1e-12);

  // An asymmetric loss sees the signed residual: longer (+2) vs shorter (-2).
  auto asym = std::make_shared<TestAsymmetric>();
  const RangeFactor longer(X(0), p_w_anchor, 5.2, 0.1, Vec3::Zero(), asym);
  const RangeFactor shorter(X(0), p_w_anchor, 4.8, 0.1, Vec3::Zero(), asym);
  EXPECT_NEAR(longer.error(x), 0.125 * 4.0, 1e-9);
  EXPECT_NEAR(shorter.error(x), 0.5 * 4.0, 1e-9);
}

TEST(RangeFactor, InvalidArgumentsThrow) {
  const Vec3 lever = Vec3::Zero();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, 0.0, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, -0.1, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, nan, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), L(1), nan, 0.1, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, 0.1, Vec3(nan, 0, 0)), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), X(0), 5.0, 0.1, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), Vec3(0, 0, nan), 5.0, 0.1, lever), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), Vec3(1, 2, 3), 5.0, 0.0, lever), std::invalid_argument);
  try {
    RangeFactor(X(0), L(1), 5.0, -1.0, lever);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sigma_m"), std::string::npos) << e.what();
  }
}

TEST(RangeFactor, VerticalWeightScalesTheSeparationTheRangeSees) {
  // Tag 1 m below the anchor, 4 m away horizontally; the weight pins the
  // prediction's vertical separation to dz_ref + w (dz - dz_ref).
  const Vec3 p_w_anchor(4, 0, 2.5);
  const double dz_ref_m = 1.4 - 2.5;  // a reference height of 1.4 m
  Values x;
  x.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 1.5)));
  RangeFactor f(X(0), p_w_anchor, 4.2, 0.1, Vec3::Zero());
  EXPECT_NEAR(f.predictedRange(x), std::hypot(4.0, 1.0), 1e-12);
  f.setVerticalWeight(0.0, dz_ref_m);
  EXPECT_NEAR(f.predictedRange(x), std::hypot(4.0, 1.1), 1e-12);  // at the reference whatever the state's height
  Values higher;
  higher.insert(X(0), Pose3(Mat3::Identity(), Vec3(0, 0, 2.0)));
  EXPECT_NEAR(f.predictedRange(higher), f.predictedRange(x), 1e-12);
  Residual r;
  Jacobians H;
  f.evaluate(x, r, &H);
  EXPECT_EQ(H[0](0, 5), 0.0);  // no height information at all
  EXPECT_NE(H[0](0, 3), 0.0);  // the horizontal stays
  f.setVerticalWeight(0.5, dz_ref_m);
  EXPECT_NEAR(f.predictedRange(x), std::hypot(4.0, 1.1 - 0.5 * 0.1), 1e-12);
  EXPECT_DOUBLE_EQ(f.verticalWeight(), 0.5);

  // An anchor variable's height is weighted the same: with w = 0 neither the
  // tag's nor the anchor's height moves the prediction.
  RangeFactor fv(X(0), L(3), 4.2, 0.1, Vec3::Zero());
  fv.setVerticalWeight(0.0, dz_ref_m);
  const double h0 = fv.predictedRange(poseAndAnchor(Pose3(Mat3::Identity(), Vec3(0, 0, 1.5)), p_w_anchor));
  EXPECT_NEAR(fv.predictedRange(poseAndAnchor(Pose3(Mat3::Identity(), Vec3(0, 0, 1.5)), p_w_anchor + Vec3(0, 0, 0.7))),
              h0, 1e-12);
  fv.evaluate(poseAndAnchor(Pose3(Mat3::Identity(), Vec3(0, 0, 1.5)), p_w_anchor), r, &H);
  EXPECT_EQ(H[1](0, 2), 0.0);
  EXPECT_NE(H[1](0, 0), 0.0);
}

TEST(RangeFactor, JacobiansMatchWithAVerticalWeight) {
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> weight(0.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 6.0);
    const double z = (T_w_b.transformFrom(p_b_tag) - p_w_anchor).norm() + randomVec(rng, 0.3).x();
    const double w = weight(rng);
    const double dz_ref = randomVec(rng, 2.0).z();
    RangeFactor fv(X(0), L(3), z, 0.1, p_b_tag);
    fv.setVerticalWeight(w, dz_ref);
    EXPECT_TRUE(testing::jacobiansMatch(fv, poseAndAnchor(T_w_b, p_w_anchor), 1e-6)) << "sample " << i;
    RangeFactor fc(X(0), p_w_anchor, z, 0.1, p_b_tag);
    fc.setVerticalWeight(w, dz_ref);
    Values x;
    x.insert(X(0), T_w_b);
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(RangeFactor, ARangeAfterItsStateSeesTheTagMovedOnByTheStatesVelocity) {
  // Walking at 1.5 m/s along x; the range is measured 40 ms after the state.
  const Pose3 T_w_b(so3::exp(Vec3(0, 0, 0.3)), Vec3(1, 2, 1.5));
  const Vec3 p_b_tag(0.06, 0.0, 0.1);
  const Vec3 v_w(1.5, 0.0, 0.0);
  const Vec3 p_w_anchor(6, 2, 2.5);
  const double dt_s = 0.04;
  const double truth_m = (T_w_b.transformFrom(p_b_tag) + dt_s * v_w - p_w_anchor).norm();
  const RangeFactor f(X(0), L(3), truth_m, 0.1, p_b_tag, nullptr, RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(f.keys().size(), 3u);
  EXPECT_EQ(f.keys()[2], V(0));
  EXPECT_TRUE(f.hasTimeOffset());
  EXPECT_DOUBLE_EQ(f.timeOffset(), dt_s);
  Values x = poseAndAnchor(T_w_b, p_w_anchor);
  x.insert(V(0), v_w);
  EXPECT_NEAR(f.predictedRange(x), truth_m, 1e-12);
  Residual r;
  Jacobians H;
  f.evaluate(x, r, &H);
  EXPECT_NEAR(r(0), 0.0, 1e-10);
  // Moving towards the anchor shortens the prediction: the velocity Jacobian
  // is dt times the position's.
  EXPECT_TRUE(H[2].isApprox(dt_s * H[0].rightCols<3>() * T_w_b.R.transpose(), 1e-12));
  // The same range without the offset is predicted 6 cm too long.
  const RangeFactor plain(X(0), L(3), truth_m, 0.1, p_b_tag);
  EXPECT_NEAR(plain.predictedRange(x) - truth_m, 0.06 * (p_w_anchor - T_w_b.transformFrom(p_b_tag)).normalized().x(), 2e-3);
  EXPECT_FALSE(plain.hasTimeOffset());
  EXPECT_EQ(plain.timeOffset(), 0.0);

  // A constant anchor: keys {pose, velocity}.
  const RangeFactor fc(X(0), p_w_anchor, truth_m, 0.1, p_b_tag, nullptr, RangeTimeOffset{V(0), dt_s});
  ASSERT_EQ(fc.keys().size(), 2u);
  EXPECT_EQ(fc.keys()[1], V(0));
  EXPECT_NEAR(fc.predictedRange(x), truth_m, 1e-12);
}

TEST(RangeFactor, JacobiansMatchWithATimeOffset) {
  std::mt19937 rng(14);
  std::uniform_real_distribution<double> weight(0.0, 1.0);
  std::uniform_real_distribution<double> offset(-0.05, 0.05);
  for (int i = 0; i < 200; ++i) {
    const Pose3 T_w_b = randomPose(rng, 5.0);
    const Vec3 p_b_tag = randomVec(rng, 0.3);
    const Vec3 p_w_anchor = randomVec(rng, 6.0);
    const Vec3 v_w = randomVec(rng, 2.0);
    const RangeTimeOffset dt{V(0), offset(rng)};
    const double z = (T_w_b.transformFrom(p_b_tag) + dt.dt_s * v_w - p_w_anchor).norm() + randomVec(rng, 0.3).x();
    RangeFactor fv(X(0), L(3), z, 0.1, p_b_tag, nullptr, dt);
    RangeFactor fc(X(0), p_w_anchor, z, 0.1, p_b_tag, nullptr, dt);
    if (i % 2 == 1) {  // with a vertical weight too
      fv.setVerticalWeight(weight(rng), randomVec(rng, 2.0).z());
      fc.setVerticalWeight(fv.verticalWeight(), randomVec(rng, 2.0).z());
    }
    Values x = poseAndAnchor(T_w_b, p_w_anchor);
    x.insert(V(0), v_w);
    EXPECT_TRUE(testing::jacobiansMatch(fv, x, 1e-6)) << "sample " << i;
    EXPECT_TRUE(testing::jacobiansMatch(fc, x, 1e-6)) << "sample " << i;
  }
}

TEST(RangeFactor, ABadTimeOffsetThrows) {
  const Vec3 lever = Vec3::Zero();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, 0.1, lever, nullptr, RangeTimeOffset{V(0), nan}), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), Vec3(1, 2, 3), 5.0, 0.1, lever, nullptr, RangeTimeOffset{V(0), nan}),
               std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), L(1), 5.0, 0.1, lever, nullptr, RangeTimeOffset{L(1), 0.01}), std::invalid_argument);
  EXPECT_THROW(RangeFactor(X(0), Vec3(1, 2, 3), 5.0, 0.1, lever, nullptr, RangeTimeOffset{X(0), 0.01}),
               std::invalid_argument);
}

TEST(RangeFactor, VerticalWeightOutsideItsRangeThrows) {
  RangeFactor f(X(0), L(1), 5.0, 0.1, Vec3::Zero());
  EXPECT_THROW(f.setVerticalWeight(-0.1, 1.0), std::invalid_argument);
  EXPECT_THROW(f.setVerticalWeight(1.5, 1.0), std::invalid_argument);
  EXPECT_THROW(f.setVerticalWeight(std::nan(""), 1.0), std::invalid_argument);
  EXPECT_THROW(f.setVerticalWeight(0.5, std::nan("")), std::invalid_argument);
  EXPECT_DOUBLE_EQ(f.verticalWeight(), 1.0);
}

TEST(RangeFactor, WrongVariableTypeThrows) {
  const RangeFactor f(X(0), L(1), 5.0, 0.1, Vec3::Zero());
  Values x;
  x.insert(X(0), Vec3(1, 2, 3));  // not a pose
  x.insert(L(1), Vec3(0, 0, 0));
  EXPECT_THROW(static_cast<void>(f.error(x)), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
