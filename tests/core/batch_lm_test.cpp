#include "estimation/solver/batch_lm.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <random>

#include "estimation/solver/normal_equations.h"
#include "math/so3.h"
#include "support/numerical_jacobian.h"
#include "support/random_states.h"

namespace rilo {
namespace {

using testing::randomVec;

// ----------------------------------------------------------------------------
// Test-local factors (the real range and IMU factors live elsewhere).

/// x - z = noise, Vec3 variable.
class Vec3PriorFactor : public Factor {
 public:
  Vec3PriorFactor(Key k, const Vec3& z, double sigma) : Factor({k}), z_(z), inv_sigma_(1.0 / sigma) {}
  int dim() const override { return 3; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    r = inv_sigma_ * (x.vec3(keys()[0]) - z_);
    if (H) (*H)[0] = inv_sigma_ * Mat3::Identity();
  }

 private:
  Vec3 z_;
  double inv_sigma_;
};

/// x_j - x_i - z = noise, Vec3 variables: a linear factor.
class Vec3BetweenFactor : public Factor {
 public:
  Vec3BetweenFactor(Key i, Key j, const Vec3& z, double sigma) : Factor({i, j}), z_(z), inv_sigma_(1.0 / sigma) {}
  int dim() const override { return 3; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    r = inv_sigma_ * (x.vec3(keys()[1]) - x.vec3(keys()[0]) - z_);
    if (H) {
      (*H)[0] = -inv_sigma_ * Mat3::Identity();
      (*H)[1] = inv_sigma_ * Mat3::Identity();
    }
  }

 private:
  Vec3 z_;
  double inv_sigma_;
};

/// local(z, T) = noise, Pose3 variable; sigmas for rotation (rad) and position (m).
class Pose3PriorFactor : public Factor {
 public:
  Pose3PriorFactor(Key k, const Pose3& z, double sigma_rot, double sigma_pos)
      : Factor({k}), z_(z), w_rot_(1.0 / sigma_rot), w_pos_(1.0 / sigma_pos) {}
  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Pose3& T = x.pose(keys()[0]);
    const Vec6 e = z_.local(T);
    r.resize(6);
    r.head<3>() = w_rot_ * e.head<3>();
    r.tail<3>() = w_pos_ * e.tail<3>();
    if (H) {
      JacobianBlock& J = (*H)[0];
      J.setZero(6, 6);
      J.block<3, 3>(0, 0) = w_rot_ * so3::rightJacobianInverse(e.head<3>());
      J.block<3, 3>(3, 3) = w_pos_ * z_.R.transpose() * T.R;
    }
  }

 private:
  Pose3 z_;
  double w_rot_, w_pos_;
};

/// local(z_ij, T_i^-1 T_j) = noise.
class Pose3BetweenFactor : public Factor {
 public:
  Pose3BetweenFactor(Key i, Key j, const Pose3& z_ij, double sigma_rot, double sigma_pos)
      : Factor({i, j}), z_(z_ij), w_rot_(1.0 / sigma_rot), w_pos_(1.0 / sigma_pos) {}
  int dim() const override { return 6; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Pose3& Ti = x.pose(keys()[0]);
    const Pose3& Tj = x.pose(keys()[1]);
    const Mat3 E = z_.R.transpose() * Ti.R.transpose() * Tj.R;
    const Vec3 d = Ti.R.transpose() * (Tj.p - Ti.p);
    const Vec3 e_rot = so3::log(E);
    r.resize(6);
    r.head<3>() = w_rot_ * e_rot;
    r.tail<3>() = w_pos_ * z_.R.transpose() * (d - z_.p);
    if (H) {
      const Mat3 Jr_inv = so3::rightJacobianInverse(e_rot);
      JacobianBlock& Ji = (*H)[0];
      JacobianBlock& Jj = (*H)[1];
      Ji.setZero(6, 6);
      Jj.setZero(6, 6);
      Ji.block<3, 3>(0, 0) = -w_rot_ * Jr_inv * Tj.R.transpose() * Ti.R;
      Ji.block<3, 3>(3, 0) = w_pos_ * z_.R.transpose() * so3::hat(d);
      Ji.block<3, 3>(3, 3) = -w_pos_ * z_.R.transpose();
      Jj.block<3, 3>(0, 0) = w_rot_ * Jr_inv;
      Jj.block<3, 3>(3, 3) = w_pos_ * z_.R.transpose() * Ti.R.transpose() * Tj.R;
    }
  }

 private:
  Pose3 z_;
  double w_rot_, w_pos_;
};

/// Range from a variable point (Pose3 origin or Vec3) to a known point:
/// r = (measured - |p - a|) / sigma, positive when measured longer.
class RangeToPointFactor : public Factor {
 public:
  RangeToPointFactor(Key k, const Vec3& a_w, double range_m, double sigma, RobustLossPtr loss = nullptr)
      : Factor({k}, std::move(loss)), a_w_(a_w), range_m_(range_m), inv_sigma_(1.0 / sigma) {}
  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override {
    const Variable& v = x.at(keys()[0]);
    const Pose3* T = std::get_if<Pose3>(&v);
    const Vec3 p = T ? T->p : std::get<Vec3>(v);
    const Vec3 diff = p - a_w_;
    const double dist = diff.norm();
    r.resize(1);
    r(0) = inv_sigma_ * (range_m_ - dist);
    if (H) {
      const Eigen::RowVector3d du = -inv_sigma_ * diff.transpose() / dist;
      if (T) {
        (*H)[0].setZero(1, 6);
        (*H)[0].block<1, 3>(0, 3) = du * T->R;
      } else {
        (*H)[0] = du;
      }
    }
  }

 private:
  Vec3 a_w_;
  double range_m_;
  double inv_sigma_;
};

/// Test-local Cauchy loss: rho = c^2/2 log(1 + r^2/c^2).
class TestCauchyLoss : public RobustLoss {
 public:
  explicit TestCauchyLoss(double c) : c2_(c * c) {}
  double loss(double r) const override { return 0.5 * c2_ * std::log1p(r * r / c2_); }
  double derivative(double r) const override { return r / (1.0 + r * r / c2_); }
  std::string name() const override { return "test-cauchy"; }

 private:
  double c2_;
};

// ----------------------------------------------------------------------------
// Dense references.

Pose3 perturb(const Pose3& T, std::mt19937& rng, double rot, double pos) {
  Vec6 xi;
  xi << randomVec(rng, rot), randomVec(rng, pos);
  return T.retract(xi);
}

/// Dense J (robust-weighted, whitened) and r with columns in `order`.
struct DenseSystem {
  Eigen::MatrixXd J;
  Eigen::VectorXd r;
  std::vector<int> offset;
};

DenseSystem denseLinearize(const FactorGraph& g, const Values& x, const std::vector<Key>& order) {
  DenseSystem s;
  s.offset.push_back(0);
  for (Key k : order) s.offset.push_back(s.offset.back() + x.dim(k));
  int m = 0;
  for (const auto& f : g) m += f->dim();
  s.J.setZero(m, s.offset.back());
  s.r.setZero(m);
  int row = 0;
  Residual r;
  Jacobians H;
  for (const auto& f : g) {
    f->linearize(x, r, H);
    s.r.segment(row, r.size()) = r;
    for (std::size_t k = 0; k < f->keys().size(); ++k) {
      const auto pos = static_cast<std::size_t>(std::find(order.begin(), order.end(), f->keys()[k]) - order.begin());
      s.J.block(row, s.offset[pos], r.size(), H[k].cols()) = H[k];
    }
    row += static_cast<int>(r.size());
  }
  return s;
}

std::vector<Key> sortedGraphKeys(const FactorGraph& g) {
  std::vector<Key> keys;
  for (const auto& f : g) keys.insert(keys.end(), f->keys().begin(), f->keys().end());
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  return keys;
}

void retractAll(Values& x, const std::vector<Key>& order, const std::vector<int>& offset, const Eigen::VectorXd& d) {
  for (std::size_t i = 0; i < order.size(); ++i) x.retractInPlace(order[i], d.data() + offset[i]);
}

/// Plain dense Gauss-Newton; asserts convergence (step below 1e-12).
Values denseGaussNewton(const FactorGraph& g, Values x) {
  const std::vector<Key> order = sortedGraphKeys(g);
  for (int it = 0; it < 50; ++it) {
    const DenseSystem s = denseLinearize(g, x, order);
    const Eigen::VectorXd d = (s.J.transpose() * s.J).ldlt().solve(-s.J.transpose() * s.r);
    retractAll(x, order, s.offset, d);
    if (d.lpNorm<Eigen::Infinity>() < 1e-12) return x;
  }
  ADD_FAILURE() << "dense Gauss-Newton did not converge";
  return x;
}

double maxTangentDistance(const Values& a, const Values& b, const std::vector<Key>& keys) {
  double m = 0.0;
  for (Key k : keys) m = std::max(m, localVariable(a.at(k), b.at(k)).lpNorm<Eigen::Infinity>());
  return m;
}

// ----------------------------------------------------------------------------
// Problems.

const std::vector<Vec3> kAnchors = {Vec3(0, 0, 0.2), Vec3(12, 0, 2.8), Vec3(0, 11, 1.5), Vec3(12, 11, 0.4),
                                    Vec3(6, 5, 3.5)};

struct Problem {
  FactorGraph graph;
  Values truth;
  Values initial;
};

/// Pose chain (prior on x0, between factors) with ranges from every pose to
/// the known anchors and to one unknown point l0; noisy measurements.
Problem trilaterationChain(int n_poses, double init_rot, double init_pos, unsigned seed, bool prior = true,
                           RobustLossPtr range_loss = nullptr, int n_outliers = 0) {
  std::mt19937 rng(seed);
  Problem p;
  for (int i = 0; i < n_poses; ++i) {
    const double t = 0.3 * i;
    const Pose3 T(so3::exp(Vec3(0.1 * std::sin(t), 0.2 * std::cos(0.5 * t), 0.4 * t)),
                  Vec3(6 + 4 * std::cos(t), 5 + 3 * std::sin(t), 1.2 + 0.3 * std::sin(2 * t)));
    p.truth.insert(sym::X(static_cast<std::uint64_t>(i)), T);
  }
  const Vec3 l0(3.0, 8.0, 2.0);
  p.truth.insert(sym::L(0), l0);
  if (prior) {
    p.graph.emplace<Pose3PriorFactor>(sym::X(0), perturb(p.truth.pose(sym::X(0)), rng, 0.01, 0.01), 0.01, 0.01);
  }
  for (int i = 0; i + 1 < n_poses; ++i) {
    const Key ki = sym::X(static_cast<std::uint64_t>(i)), kj = sym::X(static_cast<std::uint64_t>(i + 1));
    const Pose3& Ti = p.truth.pose(ki);
    const Pose3& Tj = p.truth.pose(kj);
    const Pose3 T_ij(Ti.R.transpose() * Tj.R, Ti.R.transpose() * (Tj.p - Ti.p));
    p.graph.emplace<Pose3BetweenFactor>(ki, kj, perturb(T_ij, rng, 0.01, 0.03), 0.01, 0.03);
  }
  std::normal_distribution<double> range_noise(0.0, 0.05);
  int outliers = 0;
  for (int i = 0; i < n_poses; ++i) {
    const Key k = sym::X(static_cast<std::uint64_t>(i));
    const Vec3 pos = p.truth.pose(k).p;
    for (const Vec3& a : kAnchors) {
      double z = (pos - a).norm() + range_noise(rng);
      if (outliers < n_outliers && (i * 7 + static_cast<int>(a.x())) % 5 == 0) {
        z += 2.0;  // NLOS: measured too long
        ++outliers;
      }
      p.graph.emplace<RangeToPointFactor>(k, a, z, 0.05, range_loss);
    }
    if (i % 2 == 0) p.graph.emplace<RangeToPointFactor>(sym::L(0), pos, (pos - l0).norm() + range_noise(rng), 0.05);
  }
  for (const auto& [k, v] : p.truth) {
    if (const Pose3* T = std::get_if<Pose3>(&v)) {
      p.initial.insert(k, perturb(*T, rng, init_rot, init_pos));
    } else {
      p.initial.insert(k, Vec3(std::get<Vec3>(v) + randomVec(rng, init_pos)));
    }
  }
  return p;
}

/// Linear problem: Vec3 points with two priors and between factors.
Problem linearNetwork(int n, unsigned seed) {
  std::mt19937 rng(seed);
  Problem p;
  for (int i = 0; i < n; ++i) p.truth.insert(sym::L(static_cast<std::uint64_t>(i)), randomVec(rng, 5.0));
  p.graph.emplace<Vec3PriorFactor>(sym::L(0), Vec3(p.truth.vec3(sym::L(0)) + randomVec(rng, 0.1)), 0.1);
  p.graph.emplace<Vec3PriorFactor>(sym::L(3), Vec3(p.truth.vec3(sym::L(3)) + randomVec(rng, 0.1)), 0.2);
  for (int i = 0; i < n; ++i) {
    for (int j : {i + 1, i + 4}) {
      if (j >= n) continue;
      const Key ki = sym::L(static_cast<std::uint64_t>(i)), kj = sym::L(static_cast<std::uint64_t>(j));
      const Vec3 z = p.truth.vec3(kj) - p.truth.vec3(ki) + randomVec(rng, 0.05);
      p.graph.emplace<Vec3BetweenFactor>(ki, kj, z, 0.05 + 0.01 * (i % 3));
    }
  }
  for (const auto& [k, v] : p.truth) p.initial.insert(k, Vec3(std::get<Vec3>(v) + randomVec(rng, 3.0)));
  return p;
}

// ----------------------------------------------------------------------------
// Factor Jacobians.

TEST(BatchLmTestFactors, JacobiansMatchNumerical) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < 20; ++trial) {
    // Random states, including rotations near pi and tiny differences.
    const double rot_scale = trial < 10 ? 1.0 : 1e-7;
    Values x;
    const Pose3 Ta(so3::exp(randomVec(rng, trial == 5 ? 3.0 : 1.0)), randomVec(rng, 3.0));
    const Pose3 Tb = Ta.retract((Vec6() << randomVec(rng, rot_scale), randomVec(rng, 1.0)).finished());
    x.insert(sym::X(0), Ta);
    x.insert(sym::X(1), Tb);
    x.insert(sym::L(0), randomVec(rng, 2.0));
    x.insert(sym::L(1), randomVec(rng, 2.0));
    const Pose3 z = perturb(Pose3(Ta.R.transpose() * Tb.R, Ta.R.transpose() * (Tb.p - Ta.p)), rng, 0.1, 0.1);
    EXPECT_TRUE(testing::jacobiansMatch(Pose3BetweenFactor(sym::X(0), sym::X(1), z, 0.1, 0.2), x, 1e-6));
    EXPECT_TRUE(testing::jacobiansMatch(Pose3PriorFactor(sym::X(1), perturb(Tb, rng, 0.2, 0.5), 0.1, 0.2), x, 1e-6));
    EXPECT_TRUE(testing::jacobiansMatch(RangeToPointFactor(sym::X(0), Vec3(1, 2, 3), 4.0, 0.1), x, 1e-6));
    EXPECT_TRUE(testing::jacobiansMatch(RangeToPointFactor(sym::L(0), Vec3(1, 2, 3), 4.0, 0.1), x, 1e-6));
    EXPECT_TRUE(testing::jacobiansMatch(Vec3BetweenFactor(sym::L(0), sym::L(1), Vec3(1, 0, 0), 0.1), x, 1e-6));
    EXPECT_TRUE(testing::jacobiansMatch(Vec3PriorFactor(sym::L(1), Vec3(1, 0, 0), 0.1), x, 1e-6));
  }
}

// ----------------------------------------------------------------------------
// Normal equations.

Eigen::MatrixXd denseFromUpper(const SymmetricCscView& A) {
  Eigen::MatrixXd D = Eigen::MatrixXd::Zero(A.n, A.n);
  for (int c = 0; c < A.n; ++c) {
    for (int p = A.col_ptr[c]; p < A.col_ptr[c + 1]; ++p) {
      EXPECT_LE(A.row_idx[p], c);
      if (p > A.col_ptr[c]) {
        EXPECT_LT(A.row_idx[p - 1], A.row_idx[p]);
      }
      D(A.row_idx[p], c) = A.values[p];
      D(c, A.row_idx[p]) = A.values[p];
    }
  }
  return D;
}

TEST(NormalEquations, MatchDenseJacobianProducts) {
  const Problem p = trilaterationChain(12, 0.2, 0.5, 3, true, std::make_shared<TestCauchyLoss>(1.0), 6);
  std::mt19937 rng(8);
  std::vector<Key> order = sortedGraphKeys(p.graph);
  for (int trial = 0; trial < 3; ++trial) {
    if (trial > 0) std::shuffle(order.begin(), order.end(), rng);
    NormalEquations ne;
    ne.setStructure(p.graph, p.initial, order);
    ne.linearize(p.graph, p.initial);
    const DenseSystem s = denseLinearize(p.graph, p.initial, order);
    const Eigen::MatrixXd H = s.J.transpose() * s.J;
    ASSERT_EQ(ne.dim(), H.cols());
    EXPECT_LT((denseFromUpper(ne.hessian()) - H).cwiseAbs().maxCoeff(), 1e-9 * H.cwiseAbs().maxCoeff());
    EXPECT_LT((ne.gradient() - s.J.transpose() * s.r).cwiseAbs().maxCoeff(),
              1e-9 * std::max(1.0, ne.gradient().norm()));
    for (std::size_t pos = 0; pos < order.size(); ++pos) {
      EXPECT_EQ(ne.position(order[pos]), pos);
      EXPECT_EQ(ne.offset(pos), s.offset[pos]);
    }
    for (std::size_t i = 0; i < ne.diagonalIndex().size(); ++i) {
      EXPECT_DOUBLE_EQ(ne.hessianValues()[static_cast<std::size_t>(ne.diagonalIndex()[i])],
                       H(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(i)));
    }
    const Eigen::VectorXd v = Eigen::VectorXd::Random(ne.dim());
    Eigen::VectorXd Hv;
    ne.multiplyHessian(v, Hv);
    EXPECT_LT((Hv - H * v).norm(), 1e-9 * (H * v).norm());
    // Refilling at another point reuses the pattern and gives that point's system.
    const int nnz = ne.nonzeros();
    ne.linearize(p.graph, p.truth);
    EXPECT_EQ(ne.nonzeros(), nnz);
    const DenseSystem t = denseLinearize(p.graph, p.truth, order);
    const Eigen::MatrixXd Ht = t.J.transpose() * t.J;
    EXPECT_LT((denseFromUpper(ne.hessian()) - Ht).cwiseAbs().maxCoeff(), 1e-9 * Ht.cwiseAbs().maxCoeff());
  }
}

TEST(NormalEquations, RejectsInconsistentStructure) {
  const Problem p = linearNetwork(6, 2);
  NormalEquations ne;
  std::vector<Key> order = sortedGraphKeys(p.graph);
  order.pop_back();
  EXPECT_THROW(ne.setStructure(p.graph, p.initial, order), std::invalid_argument);  // key missing
  order = sortedGraphKeys(p.graph);
  order.push_back(order.front());
  EXPECT_THROW(ne.setStructure(p.graph, p.initial, order), std::invalid_argument);  // repeated key
  FactorGraph repeated;
  repeated.emplace<Vec3BetweenFactor>(sym::L(0), sym::L(0), Vec3::Zero(), 1.0);
  EXPECT_THROW(ne.setStructure(repeated, p.initial, std::vector<Key>{sym::L(0)}), std::invalid_argument);
  EXPECT_EQ(ne.dim(), 0);  // a failed setStructure leaves the object empty
  EXPECT_EQ(ne.numVariables(), 0u);
  NormalEquations fresh;
  fresh.linearize(FactorGraph(), p.initial);  // default-constructed: an empty system
  EXPECT_EQ(fresh.dim(), 0);
  ne.setStructure(p.graph, p.initial, sortedGraphKeys(p.graph));
  FactorGraph smaller;
  smaller.add(p.graph[0]);
  EXPECT_THROW(ne.linearize(smaller, p.initial), std::invalid_argument);
}

// ----------------------------------------------------------------------------
// Levenberg-Marquardt.

TEST(BatchLm, LinearProblemSolvesInOneStep) {
  const Problem p = linearNetwork(25, 5);
  const std::vector<Key> order = sortedGraphKeys(p.graph);
  const DenseSystem s = denseLinearize(p.graph, p.initial, order);
  const Eigen::VectorXd d = (s.J.transpose() * s.J).ldlt().solve(-s.J.transpose() * s.r);
  Values expected = p.initial;
  retractAll(expected, order, s.offset, d);
  const double optimal_error = p.graph.error(expected);

  LmParams params;
  params.lambda_initial = 0.0;  // first step is plain Gauss-Newton
  BatchLevenbergMarquardt lm(params);
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  EXPECT_TRUE(result.converged()) << result.message;
  ASSERT_FALSE(result.trace.empty());
  EXPECT_TRUE(result.trace[0].accepted);
  EXPECT_EQ(result.trace[0].attempts, 1);
  EXPECT_NEAR(result.trace[0].error, optimal_error, 1e-10 * optimal_error);
  EXPECT_LE(result.iterations, 2);
  EXPECT_LT(maxTangentDistance(values, expected, order), 1e-10);
  EXPECT_NEAR(result.final_error, optimal_error, 1e-10 * optimal_error);
  EXPECT_EQ(result.indeterminate_factorizations, 0);

  // Default (damped) settings reach the same solution in a few iterations.
  BatchLevenbergMarquardt damped;
  const auto out = damped.optimize(p.graph, p.initial);
  EXPECT_TRUE(out.result.converged()) << out.result.message;
  EXPECT_LT(maxTangentDistance(out.values, expected, order), 1e-8);
}

struct LmVariant {
  LmParams::Damping damping;
  LmParams::Ordering ordering;
};

class BatchLmVariants : public ::testing::TestWithParam<LmVariant> {};

TEST_P(BatchLmVariants, NonlinearTrilaterationConvergesToDenseGaussNewtonOptimum) {
  const Problem p = trilaterationChain(30, 0.15, 0.6, 11);
  const Values dense = denseGaussNewton(p.graph, p.initial);
  LmParams params;
  params.damping = GetParam().damping;
  params.ordering = GetParam().ordering;
  BatchLevenbergMarquardt lm(params);
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  EXPECT_TRUE(result.converged()) << toString(result.status) << ": " << result.message;
  EXPECT_LT(maxTangentDistance(values, dense, sortedGraphKeys(p.graph)), 1e-8);
  EXPECT_NEAR(result.final_error, p.graph.error(dense), 1e-9 * p.graph.error(dense));
  EXPECT_LT(result.final_error, result.initial_error);
  EXPECT_EQ(result.indeterminate_factorizations, 0);
  EXPECT_EQ(static_cast<int>(result.trace.size()), result.iterations);
}

INSTANTIATE_TEST_SUITE_P(DampingAndOrdering, BatchLmVariants,
                         ::testing::Values(LmVariant{LmParams::Damping::kMarquardt, LmParams::Ordering::kColamd},
                                           LmVariant{LmParams::Damping::kIdentity, LmParams::Ordering::kColamd},
                                           LmVariant{LmParams::Damping::kMarquardt, LmParams::Ordering::kNatural}));

TEST(BatchLm, HeavyDampingDoesNotPassForConvergence) {
  // At lambda = 1e11 every step is tiny: stopping on step or error tolerance
  // there would report the perturbed start as converged.
  const Problem p = trilaterationChain(30, 0.15, 0.6, 11);
  const Values dense = denseGaussNewton(p.graph, p.initial);
  LmParams params;
  params.lambda_initial = 1e11;
  params.step_tolerance = 1e-6;
  BatchLevenbergMarquardt lm(params);
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  EXPECT_TRUE(result.converged()) << result.message;
  EXPECT_LT(maxTangentDistance(values, dense, sortedGraphKeys(p.graph)), 1e-5);
  EXPECT_GT(result.iterations, 1);
}

TEST(BatchLm, ErrorNeverIncreasesAcrossAcceptedIterations) {
  for (unsigned seed : {1u, 2u, 3u}) {
    // Far start: rotations off by ~0.6 rad, positions by ~3 m: steps get rejected.
    const Problem p = trilaterationChain(20, 0.6, 3.0, seed);
    BatchLevenbergMarquardt lm;
    const auto [values, result] = lm.optimize(p.graph, p.initial);
    double previous = result.initial_error;
    for (const LmIteration& it : result.trace) {
      EXPECT_LE(it.error, previous) << "seed " << seed << " iteration " << it.iteration;
      if (!it.accepted) {
        EXPECT_EQ(it.error, previous);
      }
      previous = it.error;
    }
    EXPECT_EQ(previous, result.final_error);
    EXPECT_EQ(result.final_error, p.graph.error(values));
    EXPECT_LT(result.final_error, result.initial_error);
    EXPECT_TRUE(result.converged()) << "seed " << seed << ": " << result.message;
    for (std::size_t i = 1; i < result.trace.size(); ++i) EXPECT_GE(result.trace[i].time_s, result.trace[i - 1].time_s);
  }
}

// LmParams::cancel (an initialization attempt over its time budget): set
// before the solve, no iteration runs and the start comes back; cleared, the
// same solver converges as without it.
TEST(BatchLm, ACancelFlagStopsBeforeTheNextIteration) {
  const Problem p = trilaterationChain(20, 0.6, 3.0, 1u);
  std::atomic<bool> cancel{true};
  LmParams params;
  params.cancel = &cancel;
  BatchLevenbergMarquardt lm(params);
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  EXPECT_EQ(result.status, LmStatus::kCancelled) << result.message;
  EXPECT_FALSE(result.converged());
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(result.final_error, result.initial_error);
  EXPECT_STREQ(toString(result.status), "cancelled");
  cancel.store(false);
  const auto [solved, again] = lm.optimize(p.graph, p.initial);
  EXPECT_TRUE(again.converged()) << again.message;
  EXPECT_LT(again.final_error, again.initial_error);
}

TEST(BatchLm, RobustLossReachesAStationaryPointOfTheRobustCost) {
  const auto loss = std::make_shared<TestCauchyLoss>(2.0);
  const Problem p = trilaterationChain(25, 0.1, 0.5, 17, true, loss, 12);
  // The IRLS model (weights frozen at linearization) converges linearly near
  // the optimum, so ask for a tight error tolerance to test stationarity.
  LmParams params;
  params.relative_error_tolerance = 1e-14;
  BatchLevenbergMarquardt lm(params);
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  EXPECT_TRUE(result.converged()) << result.message;
  double previous = result.initial_error;
  for (const LmIteration& it : result.trace) {
    EXPECT_LE(it.error, previous);
    previous = it.error;
  }
  // sqrt(w)-scaled J^T r is the gradient of the sum of robust losses.
  NormalEquations ne;
  ne.setStructure(p.graph, values, sortedGraphKeys(p.graph));
  ne.linearize(p.graph, values);
  EXPECT_LT(ne.gradient().lpNorm<Eigen::Infinity>(), 2e-5) << result.message;  // ~1e-8 m at 0.05 m range sigma
  // Downweighting the NLOS ranges keeps the poses closer to the truth than least squares.
  const Problem ls = trilaterationChain(25, 0.1, 0.5, 17, true, nullptr, 12);
  BatchLevenbergMarquardt lm_ls;
  const auto ls_out = lm_ls.optimize(ls.graph, ls.initial);
  double robust_err = 0.0, ls_err = 0.0;
  for (int i = 0; i < 25; ++i) {
    const Key k = sym::X(static_cast<std::uint64_t>(i));
    robust_err += (values.pose(k).p - p.truth.pose(k).p).norm();
    ls_err += (ls_out.values.pose(k).p - p.truth.pose(k).p).norm();
  }
  EXPECT_LT(robust_err, ls_err);
}

TEST(BatchLm, GaugeFreeProblemReportsIndeterminateAndStillConverges) {
  // Pose chain without any prior and exact measurements: a 6-dof gauge freedom.
  Problem p;
  std::mt19937 rng(4);
  for (int i = 0; i < 10; ++i) {
    p.truth.insert(sym::X(static_cast<std::uint64_t>(i)),
                   Pose3(so3::exp(Vec3(0.0, 0.0, 0.3 * i)), Vec3(1.0 * i, 0.5 * i * i * 0.1, 0.0)));
  }
  for (int i = 0; i + 1 < 10; ++i) {
    const Pose3& Ti = p.truth.pose(sym::X(static_cast<std::uint64_t>(i)));
    const Pose3& Tj = p.truth.pose(sym::X(static_cast<std::uint64_t>(i + 1)));
    p.graph.emplace<Pose3BetweenFactor>(sym::X(static_cast<std::uint64_t>(i)),
                                        sym::X(static_cast<std::uint64_t>(i + 1)),
                                        Pose3(Ti.R.transpose() * Tj.R, Ti.R.transpose() * (Tj.p - Ti.p)), 0.01, 0.02);
  }
  for (const auto& [k, v] : p.truth) p.initial.insert(k, perturb(std::get<Pose3>(v), rng, 0.05, 0.2));

  LmParams params;
  params.lambda_initial = 0.0;  // undamped first attempt: J^T J is singular
  BatchLevenbergMarquardt lm(params);
  BatchLevenbergMarquardt::Output out;
  ASSERT_NO_THROW(out = lm.optimize(p.graph, p.initial));
  EXPECT_GE(out.result.indeterminate_factorizations, 1);
  EXPECT_TRUE(out.result.converged()) << out.result.message;
  EXPECT_LT(out.result.final_error, 1e-12);
  // The covariance of a gauge-free system does not exist: reported, not thrown.
  std::string why;
  EXPECT_FALSE(lm.marginalCovariance(sym::X(3), &why).has_value());
  EXPECT_FALSE(why.empty());
}

TEST(BatchLm, UnconstrainedVariableReportsIndeterminate) {
  // l0 is seen by a single range: two of its three directions are free.
  Problem p = trilaterationChain(6, 0.05, 0.2, 23);
  FactorGraph g;
  for (const auto& f : p.graph) {
    if (f->keys()[0] != sym::L(0)) g.add(f);
  }
  g.emplace<RangeToPointFactor>(sym::L(0), Vec3(0, 0, 0), 3.0, 0.05);
  LmParams params;
  params.lambda_initial = 0.0;
  BatchLevenbergMarquardt lm(params);
  BatchLevenbergMarquardt::Output out;
  ASSERT_NO_THROW(out = lm.optimize(g, p.initial));
  EXPECT_GE(out.result.indeterminate_factorizations, 1);
  EXPECT_TRUE(out.result.converged()) << out.result.message;
  EXPECT_NEAR((out.values.vec3(sym::L(0))).norm(), 3.0, 1e-6);
}

TEST(BatchLm, MarginalCovarianceEqualsDenseInverseBlock) {
  const Problem p = trilaterationChain(15, 0.1, 0.3, 29);
  BatchLevenbergMarquardt lm;
  const auto [values, result] = lm.optimize(p.graph, p.initial);
  ASSERT_TRUE(result.converged()) << result.message;
  const std::vector<Key> order = sortedGraphKeys(p.graph);
  const DenseSystem s = denseLinearize(p.graph, values, order);
  const Eigen::MatrixXd cov = (s.J.transpose() * s.J).inverse();
  for (Key k : {sym::X(0), sym::X(7), sym::X(14), sym::L(0)}) {
    const auto pos = static_cast<std::size_t>(std::find(order.begin(), order.end(), k) - order.begin());
    const int d = values.dim(k);
    const Eigen::MatrixXd expected = cov.block(s.offset[pos], s.offset[pos], d, d);
    std::string why;
    const auto block = lm.marginalCovariance(k, &why);
    ASSERT_TRUE(block.has_value()) << why;
    ASSERT_EQ(block->rows(), d);
    EXPECT_LT((Eigen::MatrixXd(*block) - expected).norm(), 1e-9 * expected.norm()) << keyString(k);
  }
  EXPECT_THROW((void)lm.marginalCovariance(sym::X(99)), std::out_of_range);
  BatchLevenbergMarquardt fresh;
  EXPECT_THROW((void)fresh.marginalCovariance(sym::X(0)), std::logic_error);
}

TEST(BatchLm, ReusesStructureAndHandlesANewOne) {
  const Problem a = trilaterationChain(12, 0.1, 0.4, 31);
  const Problem b = trilaterationChain(18, 0.1, 0.4, 37);
  BatchLevenbergMarquardt lm;
  const auto first = lm.optimize(a.graph, a.initial);
  const auto again = lm.optimize(a.graph, a.initial);  // cached ordering and analysis
  EXPECT_EQ(first.result.final_error, again.result.final_error);
  EXPECT_EQ(maxTangentDistance(first.values, again.values, sortedGraphKeys(a.graph)), 0.0);
  const auto other = lm.optimize(b.graph, b.initial);  // new structure
  BatchLevenbergMarquardt fresh;
  const auto reference = fresh.optimize(b.graph, b.initial);
  EXPECT_EQ(other.result.final_error, reference.result.final_error);
}

TEST(BatchLm, CovarianceAtEqualsAZeroIterationProbeAndTheSolveAfterItAFreshOne) {
  const Problem p = trilaterationChain(15, 0.1, 0.3, 43);
  const Key x_last = sym::X(14);
  LmParams probe_params;
  probe_params.max_iterations = 0;
  BatchLevenbergMarquardt probe(probe_params);
  (void)probe.optimize(p.graph, p.initial);
  const auto expected_last = probe.marginalCovariance(x_last);
  const auto expected_first = probe.marginalCovariance(sym::X(0));
  ASSERT_TRUE(expected_last && expected_first);

  BatchLevenbergMarquardt lm;
  std::string why;
  const auto cov = lm.covarianceAt(p.graph, p.initial, x_last, &why);
  ASSERT_TRUE(cov.has_value()) << why;
  EXPECT_EQ(Eigen::MatrixXd(*cov), Eigen::MatrixXd(*expected_last));  // the same system, bit for bit
  const auto cov_first = lm.marginalCovariance(sym::X(0));
  ASSERT_TRUE(cov_first.has_value());
  EXPECT_EQ(Eigen::MatrixXd(*cov_first), Eigen::MatrixXd(*expected_first));

  // The solve from the same values reuses the probe's structure and first
  // linearization and ends exactly where a fresh solver does.
  BatchLevenbergMarquardt fresh;
  const auto reference = fresh.optimize(p.graph, p.initial);
  const auto solved = lm.optimize(p.graph, p.initial);
  ASSERT_TRUE(reference.result.converged()) << reference.result.message;
  EXPECT_EQ(solved.result.status, reference.result.status);
  EXPECT_EQ(solved.result.iterations, reference.result.iterations);
  EXPECT_EQ(solved.result.initial_error, reference.result.initial_error);
  EXPECT_EQ(solved.result.final_error, reference.result.final_error);
  EXPECT_EQ(maxTangentDistance(solved.values, reference.values, sortedGraphKeys(p.graph)), 0.0);
  const auto cov_solved = lm.marginalCovariance(x_last);
  const auto cov_reference = fresh.marginalCovariance(x_last);
  ASSERT_TRUE(cov_solved && cov_reference);
  EXPECT_EQ(Eigen::MatrixXd(*cov_solved), Eigen::MatrixXd(*cov_reference));

  // From other values the probe's linearization must not be used.
  BatchLevenbergMarquardt other;
  ASSERT_TRUE(other.covarianceAt(p.graph, p.initial, x_last).has_value());
  Values moved = p.initial;
  moved.update(sym::L(0), Vec3(p.initial.vec3(sym::L(0)) + Vec3(0.3, -0.2, 0.1)));
  const auto from_moved = other.optimize(p.graph, moved);
  const auto reference_moved = BatchLevenbergMarquardt().optimize(p.graph, moved);
  EXPECT_EQ(from_moved.result.initial_error, reference_moved.result.initial_error);
  EXPECT_EQ(from_moved.result.final_error, reference_moved.result.final_error);
  EXPECT_EQ(maxTangentDistance(from_moved.values, reference_moved.values, sortedGraphKeys(p.graph)), 0.0);
}

TEST(BatchLm, CovarianceAtReportsWhatAZeroIterationProbeWould) {
  const Problem p = trilaterationChain(10, 0.3, 1.0, 47);
  Values bad = p.initial;
  bad.update(sym::L(0), Vec3(std::nan(""), 0.0, 0.0));
  BatchLevenbergMarquardt lm;
  std::string why;
  EXPECT_FALSE(lm.covarianceAt(p.graph, bad, sym::X(0), &why).has_value());
  EXPECT_NE(why.find("not finite"), std::string::npos) << why;
  EXPECT_EQ(lm.optimize(p.graph, bad).result.status, LmStatus::kNonFiniteError);
  Values missing = p.initial;
  missing.erase(sym::L(0));
  EXPECT_THROW((void)lm.covarianceAt(p.graph, missing, sym::X(0)), std::invalid_argument);
  EXPECT_THROW((void)lm.covarianceAt(p.graph, p.initial, sym::X(99)), std::out_of_range);
}

TEST(BatchLm, TerminationStatusesWithoutExceptions) {
  const Problem p = trilaterationChain(10, 0.3, 1.0, 41);
  {
    LmParams params;
    params.max_iterations = 1;
    BatchLevenbergMarquardt lm(params);
    const auto out = lm.optimize(p.graph, p.initial);
    EXPECT_EQ(out.result.status, LmStatus::kMaxIterations);
    EXPECT_EQ(out.result.iterations, 1);
    EXPECT_LE(out.result.final_error, out.result.initial_error);
  }
  {
    // lambda may not grow at all: the first rejected step ends the run.
    LmParams params;
    params.lambda_initial = 1e-10;
    params.lambda_max = 1e-10;
    params.min_gain_ratio = 0.999999;
    BatchLevenbergMarquardt lm(params);
    const auto out = lm.optimize(p.graph, p.initial);
    EXPECT_EQ(out.result.status, LmStatus::kLambdaMaxReached) << out.result.message;
    EXPECT_GE(out.result.rejected_steps, 1);
  }
  {
    Values bad = p.initial;
    bad.update(sym::L(0), Vec3(std::nan(""), 0.0, 0.0));
    BatchLevenbergMarquardt lm;
    const auto out = lm.optimize(p.graph, bad);
    EXPECT_EQ(out.result.status, LmStatus::kNonFiniteError);
    std::string why;
    EXPECT_FALSE(lm.marginalCovariance(sym::X(0), &why).has_value());
    EXPECT_FALSE(why.empty());
  }
  {
    BatchLevenbergMarquardt lm;
    const auto out = lm.optimize(FactorGraph(), p.initial);
    EXPECT_EQ(out.result.status, LmStatus::kGradientTolerance);
    EXPECT_EQ(out.values.size(), p.initial.size());
  }
  {
    // Keys in no factor are passed through untouched.
    Values extra = p.initial;
    extra.insert(sym::L(7), Vec3(1, 2, 3));
    BatchLevenbergMarquardt lm;
    const auto out = lm.optimize(p.graph, extra);
    EXPECT_TRUE(out.result.converged());
    EXPECT_EQ(out.values.vec3(sym::L(7)), Vec3(1, 2, 3));
  }
}

TEST(BatchLm, InvalidInputThrows) {
  LmParams params;
  params.lambda_min = 0.0;
  EXPECT_THROW(BatchLevenbergMarquardt{params}, std::invalid_argument);
  params = LmParams{};
  params.max_iterations = -1;
  EXPECT_THROW(BatchLevenbergMarquardt{params}, std::invalid_argument);
  const Problem p = linearNetwork(5, 1);
  Values missing = p.initial;
  missing.erase(sym::L(2));
  BatchLevenbergMarquardt lm;
  EXPECT_THROW((void)lm.optimize(p.graph, missing), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
