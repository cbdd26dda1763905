#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <numeric>
#include <random>

#include "estimation/solver/cholmod_context.h"

namespace rilo {
namespace {

// Upper triangle of a dense symmetric matrix in CSC form (entries with
// |a_ij| > 0 plus the whole diagonal).
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

// Sparse SPD matrix: B^T B + diag, B with a few random entries per row.
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

std::vector<int> randomPermutation(int n, std::mt19937& rng) {
  std::vector<int> p(static_cast<std::size_t>(n));
  std::iota(p.begin(), p.end(), 0);
  std::shuffle(p.begin(), p.end(), rng);
  return p;
}

double relativeError(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b) {
  return (a - b).norm() / std::max(1.0, b.norm());
}

TEST(Cholmod, SolveMatchesDenseLdltOnRandomSpdMatrices) {
  std::mt19937 rng(7);
  CholmodContext ctx;
  int supernodal = 0, simplicial = 0;
  for (int trial = 0; trial < 12; ++trial) {
    const int n = 10 + 25 * trial;
    const double density = trial % 3 == 0 ? 0.3 : 0.03;
    const Eigen::MatrixXd A = randomSpd(n, density, rng);
    const UpperCsc csc(A);
    const int n_rhs = 1 + trial % 3;
    const Eigen::MatrixXd B = Eigen::MatrixXd::Random(n, n_rhs);
    const Eigen::MatrixXd expected = A.ldlt().solve(B);
    for (int mode = 0; mode < 3; ++mode) {
      // natural order, a random given order, a given order with postorder
      const std::vector<int> perm = mode == 0 ? std::vector<int>{} : randomPermutation(n, rng);
      CholmodFactor factor;
      const CholmodResult analyzed = ctx.analyze(csc.view(), perm, AnalyzeOptions{.postorder = mode == 2}, &factor);
      ASSERT_TRUE(analyzed.ok()) << analyzed.message;
      const CholmodResult factorized = ctx.factorize(csc.view(), FactorizeOptions{}, factor);
      ASSERT_TRUE(factorized.ok()) << factorized.message;
      EXPECT_TRUE(factor.isNumeric());
      (factor.isSupernodal() ? supernodal : simplicial)++;
      Eigen::MatrixXd X(n, n_rhs);
      const CholmodResult solved = ctx.solve(factor, B.data(), n_rhs, X.data());
      ASSERT_TRUE(solved.ok()) << solved.message;
      EXPECT_LT(relativeError(X, expected), 1e-10) << "n " << n << " mode " << mode;
    }
  }
  // Both CHOLMOD code paths (and both pivot checks) were exercised.
  EXPECT_GT(supernodal, 0);
  EXPECT_GT(simplicial, 0);
}

TEST(Cholmod, RefactorizeWithSamePatternReusesAnalysis) {
  std::mt19937 rng(11);
  CholmodContext ctx;
  const Eigen::MatrixXd A = randomSpd(60, 0.05, rng);
  UpperCsc csc(A);
  CholmodFactor factor;
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &factor).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::Random(60);
  for (double scale : {1.0, 3.0, 0.25}) {
    // Same pattern, new values written in place.
    Eigen::MatrixXd As = A * scale;
    As.diagonal().array() += scale;
    const UpperCsc fresh(As);
    ASSERT_EQ(fresh.values.size(), csc.values.size());
    csc.values = fresh.values;
    ASSERT_TRUE(ctx.factorize(csc.view(), {}, factor).ok());
    Eigen::VectorXd x(60);
    ASSERT_TRUE(ctx.solve(factor, b.data(), 1, x.data()).ok());
    EXPECT_LT(relativeError(x, As.ldlt().solve(b)), 1e-10);
  }
}

TEST(Cholmod, ShiftFactorizesAPlusShiftIdentity) {
  std::mt19937 rng(3);
  CholmodContext ctx;
  const Eigen::MatrixXd A = randomSpd(40, 0.1, rng);
  const UpperCsc csc(A);
  CholmodFactor factor;
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &factor).ok());
  ASSERT_TRUE(ctx.factorize(csc.view(), FactorizeOptions{.shift = 2.5}, factor).ok());
  const Eigen::VectorXd b = Eigen::VectorXd::Random(40);
  Eigen::VectorXd x(40);
  ASSERT_TRUE(ctx.solve(factor, b.data(), 1, x.data()).ok());
  const Eigen::MatrixXd shifted = A + 2.5 * Eigen::MatrixXd::Identity(40, 40);
  EXPECT_LT(relativeError(x, shifted.ldlt().solve(b)), 1e-10);
}

TEST(Cholmod, GivenOrderingIsRespected) {
  std::mt19937 rng(5);
  CholmodContext ctx;
  for (int n : {8, 50, 200}) {
    const UpperCsc csc(randomSpd(n, 0.1, rng));
    const std::vector<int> perm = randomPermutation(n, rng);
    CholmodFactor factor;
    ASSERT_TRUE(ctx.analyze(csc.view(), perm, AnalyzeOptions{.postorder = false}, &factor).ok());
    EXPECT_EQ(factor.permutation(), perm);
    CholmodFactor natural;
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, AnalyzeOptions{.postorder = false}, &natural).ok());
    std::vector<int> identity(static_cast<std::size_t>(n));
    std::iota(identity.begin(), identity.end(), 0);
    EXPECT_EQ(natural.permutation(), identity);
    EXPECT_GT(factor.factorNonzeros(), 0.0);
  }
}

TEST(Cholmod, OrderingChangesFillAsExpected) {
  // Arrow matrix: eliminating the hub first fills everything, last fills nothing.
  const int n = 30;
  Eigen::MatrixXd A = Eigen::MatrixXd::Identity(n, n) * 4.0;
  for (int i = 1; i < n; ++i) A(0, i) = A(i, 0) = 0.1;
  const UpperCsc csc(A);
  CholmodContext ctx;
  std::vector<int> hub_first(n), hub_last(n);
  std::iota(hub_first.begin(), hub_first.end(), 0);
  std::iota(hub_last.begin(), hub_last.end() - 1, 1);
  hub_last.back() = 0;
  CholmodFactor f_first, f_last;
  ASSERT_TRUE(ctx.analyze(csc.view(), hub_first, {}, &f_first).ok());
  ASSERT_TRUE(ctx.analyze(csc.view(), hub_last, {}, &f_last).ok());
  EXPECT_DOUBLE_EQ(f_first.factorNonzeros(), n * (n + 1) / 2.0);
  EXPECT_DOUBLE_EQ(f_last.factorNonzeros(), 2.0 * n - 1.0);
}

TEST(Cholmod, IndefiniteMatrixIsReportedAndRecoverable) {
  std::mt19937 rng(13);
  CholmodContext ctx;
  for (double density : {0.05, 0.6}) {  // simplicial and supernodal
    const int n = 120;
    Eigen::MatrixXd A = randomSpd(n, density, rng);
    UpperCsc csc(A);
    CholmodFactor factor;
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &factor).ok());
    // Make one diagonal entry strongly negative: indefinite.
    Eigen::MatrixXd bad = A;
    bad(n / 2, n / 2) = -1e3;
    const UpperCsc bad_csc(bad);
    csc.values = bad_csc.values;
    ::testing::internal::CaptureStderr();
    ::testing::internal::CaptureStdout();
    const CholmodResult r = ctx.factorize(csc.view(), {}, factor);
    const std::string err_out = ::testing::internal::GetCapturedStderr();
    const std::string std_out = ::testing::internal::GetCapturedStdout();
    EXPECT_EQ(r.status, CholmodStatus::kNotPositiveDefinite) << "density " << density;
    EXPECT_GE(r.failed_column, 0);
    EXPECT_FALSE(r.message.empty());
    EXPECT_FALSE(factor.isNumeric());
    EXPECT_TRUE(err_out.empty()) << err_out;  // CHOLMOD must not print
    EXPECT_TRUE(std_out.empty()) << std_out;
    if (factor.isSupernodal()) {
      // CHOLMOD itself detected it: its handler recorded the message.
      EXPECT_NE(ctx.lastMessage().find("not positive definite"), std::string::npos) << ctx.lastMessage();
    }
    const Eigen::VectorXd b = Eigen::VectorXd::Ones(n);
    Eigen::VectorXd x(n);
    EXPECT_EQ(ctx.solve(factor, b.data(), 1, x.data()).status, CholmodStatus::kInvalidInput);

    // The same factor works again once the matrix is positive definite.
    csc.values = UpperCsc(A).values;
    ASSERT_TRUE(ctx.factorize(csc.view(), {}, factor).ok());
    ASSERT_TRUE(ctx.solve(factor, b.data(), 1, x.data()).ok());
    EXPECT_LT(relativeError(x, A.ldlt().solve(b)), 1e-10);
  }
}

TEST(Cholmod, SingularMatrixIsReportedByPivotRatio) {
  // Graph Laplacian of a path (a chain of relative measurements without a
  // prior): positive semidefinite with the constant vector in its null space.
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
    ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &factor).ok());
    const CholmodResult r = ctx.factorize(csc.view(), FactorizeOptions{.min_pivot_ratio = 1e-12}, factor);
    EXPECT_EQ(r.status, CholmodStatus::kNotPositiveDefinite) << r.message;
    // A small shift makes it determinate again.
    const CholmodResult shifted =
        ctx.factorize(csc.view(), FactorizeOptions{.shift = 1e-6, .min_pivot_ratio = 1e-12}, factor);
    EXPECT_TRUE(shifted.ok()) << shifted.message;
  }
}

TEST(Cholmod, FactorOwnershipMoves) {
  std::mt19937 rng(17);
  CholmodContext ctx;
  const Eigen::MatrixXd A = randomSpd(20, 0.2, rng);
  const UpperCsc csc(A);
  CholmodFactor a;
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &a).ok());
  ASSERT_TRUE(ctx.factorize(csc.view(), {}, a).ok());
  CholmodFactor b(std::move(a));
  EXPECT_TRUE(a.empty());  // NOLINT(bugprone-use-after-move): moved-from state is specified
  EXPECT_FALSE(b.empty());
  EXPECT_TRUE(b.isNumeric());
  CholmodFactor c;
  c = std::move(b);
  EXPECT_EQ(c.size(), 20);
  const Eigen::VectorXd rhs = Eigen::VectorXd::Random(20);
  Eigen::VectorXd x(20);
  ASSERT_TRUE(ctx.solve(c, rhs.data(), 1, x.data()).ok());
  EXPECT_LT(relativeError(x, A.ldlt().solve(rhs)), 1e-10);
  c.reset();
  EXPECT_TRUE(c.empty());
}

TEST(Cholmod, MisuseThrowsInvalidArgument) {
  CholmodContext ctx;
  const UpperCsc csc(Eigen::MatrixXd::Identity(4, 4));
  EXPECT_THROW((void)ctx.analyze(csc.view(), {}, {}, nullptr), std::invalid_argument);
  CholmodFactor factor;
  const std::vector<int> not_a_perm = {0, 1, 1, 3};
  EXPECT_THROW((void)ctx.analyze(csc.view(), not_a_perm, {}, &factor), std::invalid_argument);
  EXPECT_THROW((void)ctx.factorize(csc.view(), {}, factor), std::invalid_argument);  // empty factor
  ASSERT_TRUE(ctx.analyze(csc.view(), {}, {}, &factor).ok());
  const UpperCsc bigger(Eigen::MatrixXd::Identity(5, 5));
  EXPECT_THROW((void)ctx.factorize(bigger.view(), {}, factor), std::invalid_argument);
  CholmodContext other;
  EXPECT_THROW((void)other.factorize(csc.view(), {}, factor), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
