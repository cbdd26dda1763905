// CholmodContext with AnalyzeOptions::Kernel::kSupernodalEigen: CHOLMOD's
// supernodal analysis and solve around SupernodalCholesky's numeric
// factorization. Checked against dense Eigen solves and against CHOLMOD's own
// numeric factorization (same factor up to round-off), including the
// not-positive-definite paths the batch solver relies on.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <numeric>
#include <random>

#include "estimation/solver/cholmod_context.h"

namespace rilo {
namespace {

constexpr AnalyzeOptions kEigen{.postorder = false, .kernel = AnalyzeOptions::Kernel::kSupernodalEigen};

struct UpperCsc {
  int n = 0;
  std::vector<int> col_ptr;
  std::vector<int> row_idx;
  std::vector<double> values;

  explicit UpperCsc(const Eigen::MatrixXd& A) : n(static_cast<int>(A.rows())) {
    col_ptr.push_back(0);
    for (int c = 0; c < n; ++c) {
      for (int r = 0; r <= c; ++r) {
        if (r == c || A(r, c) != 0.0) {
          row_idx.push_back(r);
          values.push_back(A(r, c));
        }
      }
      col_ptr.push_back(static_cast<int>(row_idx.size()));
    }
  }
  SymmetricCscView view() const { return {n, col_ptr.data(), row_idx.data(), values.data()}; }
};

Eigen::MatrixXd randomSpd(int n, double density, std::mt19937& rng, double diag = 0.1) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::bernoulli_distribution keep(density);
  Eigen::MatrixXd B = Eigen::MatrixXd::Zero(2 * n, n);
  for (int r = 0; r < 2 * n; ++r) {
    for (int c = 0; c < n; ++c) {
      if (keep(rng)) B(r, c) = u(rng);
    }
  }
  Eigen::MatrixXd A = B.transpose() * B;
  A.diagonal().array() += diag;
  return A;
}

/// A block chain with a dense tail: the structure of the range + IMU batch
/// (15-dim states coupled to their neighbours, 24 anchor dims seen by all).
Eigen::MatrixXd chainWithHub(int states, int state_dim, int hub_dim, std::mt19937& rng) {
  const int n = states * state_dim + hub_dim;
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(3 * n, n);
  int row = 0;
  for (int s = 0; s < states; ++s) {
    for (int k = 0; k < state_dim && row < J.rows(); ++k, ++row) {
      const int span = s + 1 < states ? 2 * state_dim : state_dim;
      for (int c = 0; c < span; ++c) J(row, s * state_dim + c) = u(rng);
      J(row, states * state_dim + (row % hub_dim)) = u(rng);
    }
  }
  Eigen::MatrixXd A = J.transpose() * J;
  A.diagonal().array() += 1e-2;
  return A;
}

std::vector<int> randomPermutation(int n, std::mt19937& rng) {
  std::vector<int> p(static_cast<std::size_t>(n));
  std::iota(p.begin(), p.end(), 0);
  std::shuffle(p.begin(), p.end(), rng);
  return p;
}

double relativeError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(1.0, b.norm());
}

TEST(SupernodalEigenKernel, SolveMatchesDenseOnRandomSpdMatrices) {
  std::mt19937 rng(7);
  CholmodContext ctx;
  for (int trial = 0; trial < 10; ++trial) {
    const int n = 5 + 30 * trial;
    const double density = trial % 3 == 0 ? 0.4 : 0.03;
    const Eigen::MatrixXd A = randomSpd(n, density, rng);
    const UpperCsc csc(A);
    const int n_rhs = 1 + trial % 3;
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, n_rhs);
    const Eigen::MatrixXd expected = A.ldlt().solve(B);
    for (bool permuted : {false, true}) {
      const std::vector<int> perm = permuted ? randomPermutation(n, rng) : std::vector<int>{};
      CholmodFactor factor;
      const CholmodResult analyzed = ctx.analyze(csc.view(), perm, kEigen, &factor);
      ASSERT_TRUE(analyzed.ok()) << analyzed.message;
      EXPECT_TRUE(factor.isSupernodal());
      const CholmodResult factorized = ctx.factorize(csc.view(), FactorizeOptions{}, factor);
      ASSERT_TRUE(factorized.ok()) << factorized.message;
      Eigen::MatrixXd X(n, n_rhs);
      ASSERT_TRUE(ctx.solve(factor, B.data(), n_rhs, X.data()).ok());
      EXPECT_LT(relativeError(X, expected), 1e-10) << "n " << n << " permuted " << permuted;
    }
  }
}

TEST(SupernodalEigenKernel, MatchesCholmodOnABlockChainWithAHub) {
  std::mt19937 rng(21);
  const Eigen::MatrixXd A = chainWithHub(40, 15, 24, rng);
  const int n = static_cast<int>(A.rows());
  const UpperCsc csc(A);
  CholmodContext ctx;
  CholmodFactor ours, theirs;
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, kEigen, &ours).ok());
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, AnalyzeOptions{}, &theirs).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::Random(n);
  for (double shift : {0.0, 1e-3}) {
    ASSERT_TRUE(ctx.factorize(csc.view(), FactorizeOptions{.shift = shift}, ours).ok());
    ASSERT_TRUE(ctx.factorize(csc.view(), FactorizeOptions{.shift = shift}, theirs).ok());
    Eigen::VectorXd x_ours(n), x_theirs(n);
    ASSERT_TRUE(ctx.solve(ours, b.data(), 1, x_ours.data()).ok());
    ASSERT_TRUE(ctx.solve(theirs, b.data(), 1, x_theirs.data()).ok());
    EXPECT_LT(relativeError(x_ours, x_theirs), 1e-12) << "shift " << shift;
    const Eigen::MatrixXd shifted = A + shift * Eigen::MatrixXd::Identity(n, n);
    EXPECT_LT(relativeError(x_ours, shifted.llt().solve(b)), 1e-10);
  }
}

TEST(SupernodalEigenKernel, RefactorizesWithNewValuesInPlace) {
  std::mt19937 rng(11);
  CholmodContext ctx;
  const Eigen::MatrixXd A = randomSpd(80, 0.05, rng);
  UpperCsc csc(A);
  CholmodFactor factor;
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, kEigen, &factor).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::Random(80);
  for (double scale : {1.0, 3.0, 0.25}) {
    Eigen::MatrixXd As = A * scale;
    As.diagonal().array() += scale;
    csc.values = UpperCsc(As).values;
    ASSERT_TRUE(ctx.factorize(csc.view(), {}, factor).ok());
    Eigen::VectorXd x(80);
    ASSERT_TRUE(ctx.solve(factor, b.data(), 1, x.data()).ok());
    EXPECT_LT(relativeError(x, As.ldlt().solve(b)), 1e-10);
  }
}

TEST(SupernodalEigenKernel, IndefiniteMatrixIsReportedAtTheCholmodColumnAndRecoverable) {
  std::mt19937 rng(13);
  CholmodContext ctx;
  for (double density : {0.05, 0.6}) {
    const int n = 120;
    const Eigen::MatrixXd A = randomSpd(n, density, rng);
    UpperCsc csc(A);
    CholmodFactor ours, theirs;
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, kEigen, &ours).ok());
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, AnalyzeOptions{.postorder = false}, &theirs).ok());
    Eigen::MatrixXd bad = A;
    bad(n / 2, n / 2) = -1e3;
    csc.values = UpperCsc(bad).values;
    const CholmodResult r = ctx.factorize(csc.view(), {}, ours);
    EXPECT_EQ(r.status, CholmodStatus::kNotPositiveDefinite) << "density " << density;
    EXPECT_FALSE(r.message.empty());
    EXPECT_FALSE(ours.isNumeric());
    const CholmodResult r_cholmod = ctx.factorize(csc.view(), {}, theirs);
    ASSERT_EQ(r_cholmod.status, CholmodStatus::kNotPositiveDefinite);
    EXPECT_EQ(r.failed_column, r_cholmod.failed_column) << "density " << density;
    const Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
    Eigen::VectorXd x(n);
    EXPECT_EQ(ctx.solve(ours, b.data(), 1, x.data()).status, CholmodStatus::kInvalidInput);

    csc.values = UpperCsc(A).values;
    ASSERT_TRUE(ctx.factorize(csc.view(), {}, ours).ok());
    ASSERT_TRUE(ctx.solve(ours, b.data(), 1, x.data()).ok());
    EXPECT_LT(relativeError(x, A.ldlt().solve(b)), 1e-10);
  }
}

TEST(SupernodalEigenKernel, SingularMatrixIsReportedByPivotRatioAndAShiftFixesIt) {
  for (int n : {10, 300}) {
    Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i + 1 < n; ++i) {
      A(i, i) += 1.0;
      A(i + 1, i + 1) += 1.0;
      A(i, i + 1) -= 1.0;
      A(i + 1, i) -= 1.0;
    }
    const UpperCsc csc(A);
    CholmodContext ctx;
    CholmodFactor factor;
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, kEigen, &factor).ok());
    const CholmodResult r = ctx.factorize(csc.view(), FactorizeOptions{.min_pivot_ratio = 1e-12}, factor);
    EXPECT_EQ(r.status, CholmodStatus::kNotPositiveDefinite) << r.message;
    const CholmodResult shifted =
        ctx.factorize(csc.view(), FactorizeOptions{.shift = 1e-6, .min_pivot_ratio = 1e-12}, factor);
    EXPECT_TRUE(shifted.ok()) << shifted.message;
  }
}

TEST(SupernodalEigenKernel, ADifferentPatternIsRejected) {
  std::mt19937 rng(3);
  CholmodContext ctx;
  const UpperCsc sparse(randomSpd(30, 0.05, rng));
  const UpperCsc dense(randomSpd(30, 1.0, rng));
  ASSERT_NE(sparse.values.size(), dense.values.size());
  CholmodFactor factor;
  ASSERT_TRUE(ctx.analyze(sparse.view(), {}, kEigen, &factor).ok());
  EXPECT_THROW((void)ctx.factorize(dense.view(), {}, factor), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
