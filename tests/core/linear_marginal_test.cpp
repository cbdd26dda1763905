// LinearMarginal: r(x) = A [local(x0_k, x_k)]_k - d over Pose3 / Vec3 / ImuBias
// keys, its error and its exact Jacobian in the retraction chart of Values,
// checked by central differences far from the linearization point.
#include "estimation/smoother/linear_marginal.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "math/so3.h"
#include "support/random_states.h"

namespace rilo {
namespace {

using sym::B;
using sym::L;
using sym::V;
using sym::X;
using testing::randomPose;
using testing::randomVec;

struct MarginalSetup {
  std::vector<Key> keys;
  Values x0;
  Eigen::MatrixXd A;
  Eigen::VectorXd d;
};

MarginalSetup makeSetup(std::mt19937& rng, int rows) {
  MarginalSetup s;
  s.keys = {X(3), V(3), B(3), L(1), X(7)};
  s.x0.insert(X(3), randomPose(rng, 3.0));
  s.x0.insert(V(3), Variable(randomVec(rng, 1.0)));
  s.x0.insert(B(3), ImuBias(randomVec(rng, 0.1), randomVec(rng, 0.01)));
  s.x0.insert(L(1), Variable(randomVec(rng, 5.0)));
  s.x0.insert(X(7), randomPose(rng, 3.0));
  const int cols = 6 + 3 + 6 + 3 + 6;
  std::normal_distribution<double> n01(0.0, 1.0);
  s.A = Eigen::MatrixXd::NullaryExpr(rows, cols, [&] { return n01(rng); });
  s.d = Eigen::VectorXd::NullaryExpr(rows, [&] { return n01(rng); });
  return s;
}

/// x far from x0: rotations up to ~2.5 rad away (below the Log cut at pi),
/// positions metres away, biases far off.
Values farFrom(const Values& x0, std::mt19937& rng) {
  Values x;
  std::uniform_real_distribution<double> angle(0.5, 2.5);
  for (Key k : x0.keys()) {
    const Variable& v = x0.at(k);
    if (const auto* T = std::get_if<Pose3>(&v)) {
      const Vec3 axis = randomVec(rng, 1.0).normalized();
      x.insert(k, Pose3(T->R * so3::exp(angle(rng) * axis), T->p + randomVec(rng, 4.0)));
    } else if (const auto* b = std::get_if<ImuBias>(&v)) {
      x.insert(k, ImuBias(b->accel + randomVec(rng, 1.0), b->gyro + randomVec(rng, 0.5)));
    } else {
      x.insert(k, Variable(std::get<Vec3>(v) + randomVec(rng, 4.0)));
    }
  }
  return x;
}

TEST(LinearMarginal, ResidualAtLinearizationPointIsMinusD) {
  std::mt19937 rng(1);
  for (int rows : {1, 7, 24, 30}) {
    const MarginalSetup s = makeSetup(rng, rows);
    const LinearMarginal m(s.keys, s.x0, s.A, s.d);
    EXPECT_EQ(m.rows(), rows);
    EXPECT_EQ(m.cols(), 24);
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    m.evaluate(s.x0, r, &J);
    EXPECT_LT((r + s.d).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_LT((J - s.A).cwiseAbs().maxCoeff(), 1e-12) << "at x0 the Jacobian is A";
    EXPECT_NEAR(m.error(s.x0), 0.5 * s.d.squaredNorm(), 1e-12 * s.d.squaredNorm());
  }
}

TEST(LinearMarginal, ResidualIsAffineInTheLocalCoordinates) {
  std::mt19937 rng(2);
  const MarginalSetup s = makeSetup(rng, 10);
  const LinearMarginal m(s.keys, s.x0, s.A, s.d);
  const Values x = farFrom(s.x0, rng);
  Eigen::VectorXd local(24);
  int offset = 0;
  for (Key k : s.keys) {
    const Eigen::VectorXd l = localVariable(s.x0.at(k), x.at(k));
    local.segment(offset, l.size()) = l;
    offset += static_cast<int>(l.size());
  }
  Eigen::VectorXd r;
  m.evaluate(x, r);
  EXPECT_LT((r - (s.A * local - s.d)).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_NEAR(m.error(x), 0.5 * r.squaredNorm(), 1e-10 * r.squaredNorm());
  // Extra keys in x are ignored.
  Values more = x;
  more.insert(X(99), Pose3());
  Eigen::VectorXd r_more;
  m.evaluate(more, r_more);
  EXPECT_EQ(r_more, r);
}

TEST(LinearMarginal, JacobianMatchesCentralDifferencesFarFromX0) {
  std::mt19937 rng(3);
  const double h = 1e-6;
  for (int trial = 0; trial < 20; ++trial) {
    const MarginalSetup s = makeSetup(rng, 9);
    const LinearMarginal m(s.keys, s.x0, s.A, s.d);
    const Values x = farFrom(s.x0, rng);
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    m.evaluate(x, r, &J);
    ASSERT_EQ(J.rows(), 9);
    ASSERT_EQ(J.cols(), 24);
    int col = 0;
    for (Key k : s.keys) {
      const int dim = x.dim(k);
      for (int i = 0; i < dim; ++i, ++col) {
        Vec6 delta = Vec6::Zero();
        Values xp = x, xm = x;
        delta(i) = h;
        xp.update(k, retractVariable(x.at(k), delta.data()));
        delta(i) = -h;
        xm.update(k, retractVariable(x.at(k), delta.data()));
        Eigen::VectorXd rp, rm;
        m.evaluate(xp, rp);
        m.evaluate(xm, rm);
        const Eigen::VectorXd numeric = (rp - rm) / (2.0 * h);
        const double scale = std::max(1.0, numeric.cwiseAbs().maxCoeff());
        EXPECT_LT((J.col(col) - numeric).cwiseAbs().maxCoeff(), 1e-6 * scale)
            << "trial " << trial << " key " << keyString(k) << " tangent coordinate " << i;
      }
    }
  }
}

TEST(LinearMarginal, JacobianNearTheLogCutAtPi) {
  // Rotation of x relative to x0 close to pi: Jr^-1 is large but finite.
  std::mt19937 rng(4);
  MarginalSetup s = makeSetup(rng, 6);
  s.keys = {X(3)};
  s.A = s.A.leftCols(6).eval();
  const LinearMarginal m(s.keys, s.x0, s.A, s.d);
  Values x;
  const Pose3& T0 = s.x0.pose(X(3));
  x.insert(X(3), Pose3(T0.R * so3::exp(Vec3(0.0, 0.0, 3.0)), T0.p + Vec3(1.0, -2.0, 0.5)));
  Eigen::VectorXd r;
  Eigen::MatrixXd J;
  m.evaluate(x, r, &J);
  const double h = 1e-7;
  for (int i = 0; i < 6; ++i) {
    Vec6 delta = Vec6::Zero();
    delta(i) = h;
    Values xp = x, xm = x;
    xp.update(X(3), retractVariable(x.at(X(3)), delta.data()));
    delta(i) = -h;
    xm.update(X(3), retractVariable(x.at(X(3)), delta.data()));
    Eigen::VectorXd rp, rm;
    m.evaluate(xp, rp);
    m.evaluate(xm, rm);
    const Eigen::VectorXd numeric = (rp - rm) / (2.0 * h);
    EXPECT_LT((J.col(i) - numeric).cwiseAbs().maxCoeff(), 1e-5 * std::max(1.0, numeric.cwiseAbs().maxCoeff()))
        << "coordinate " << i;
  }
}

TEST(LinearMarginal, RejectsInconsistentInput) {
  std::mt19937 rng(5);
  const MarginalSetup s = makeSetup(rng, 4);
  auto expectInvalid = [](auto&& make, const std::string& must_mention) {
    try {
      make();
      ADD_FAILURE() << "no exception; expected one mentioning '" << must_mention << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(must_mention), std::string::npos) << e.what();
    }
  };
  // A with too few / too many columns for the keys.
  expectInvalid([&] { LinearMarginal(s.keys, s.x0, s.A.leftCols(23), s.d); }, "column");
  Eigen::MatrixXd wide(4, 25);
  wide.setOnes();
  expectInvalid([&] { LinearMarginal(s.keys, s.x0, wide, s.d); }, "column");
  // d with the wrong number of rows.
  expectInvalid([&] { LinearMarginal(s.keys, s.x0, s.A, Eigen::VectorXd::Zero(5)); }, "row");
  expectInvalid([&] { LinearMarginal(s.keys, s.x0, s.A, Eigen::VectorXd::Zero(3)); }, "row");
  // A key without a linearization point: the message names it.
  Values missing = s.x0;
  missing.erase(L(1));
  expectInvalid([&] { LinearMarginal(s.keys, missing, s.A, s.d); }, keyString(L(1)));
  // No keys.
  EXPECT_THROW(LinearMarginal({}, s.x0, Eigen::MatrixXd(4, 0), s.d), std::invalid_argument);
}

TEST(LinearMarginal, EvaluateThrowsForAMissingKey) {
  std::mt19937 rng(6);
  const MarginalSetup s = makeSetup(rng, 4);
  const LinearMarginal m(s.keys, s.x0, s.A, s.d);
  Values x = s.x0;
  x.erase(V(3));
  Eigen::VectorXd r;
  EXPECT_ANY_THROW(m.evaluate(x, r));
}

}  // namespace
}  // namespace rilo
