// staircaseQrInPlace against Eigen's dense Householder QR. R is unique only up
// to row signs, so the comparisons are on R^T R (= A^T A) and R^T (Q^T b)
// (= A^T b), plus the structure of the result (zeros below the diagonal, the
// residual rows) and the norm of the right-hand sides (Q is orthogonal).
#include "estimation/smoother/dense_qr.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace rilo {
namespace {

struct QrCase {
  Eigen::MatrixXd W;                      ///< [A | B], rows sorted by leading column
  int n = 0;                              ///< columns of A
  std::vector<int> rows_with_leading_le;  ///< empty: dense
};

/// Random m x (n + extra) matrix; with `leading`, row i is zero before column
/// leading[i] (a lower bound of its first nonzero, rows sorted by it), and
/// entries at or after it are nonzero with probability `density`.
QrCase makeCase(std::mt19937& rng, int m, int n, int extra, const std::vector<int>* leading = nullptr,
                double density = 1.0) {
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  QrCase c;
  c.n = n;
  c.W = Eigen::MatrixXd::Zero(m, n + extra);
  for (int i = 0; i < m; ++i) {
    const int lead = leading ? (*leading)[i] : 0;
    for (int j = lead; j < n; ++j) {
      if (u01(rng) < density) c.W(i, j) = n01(rng);
    }
    for (int j = n; j < n + extra; ++j) c.W(i, j) = n01(rng);
  }
  if (leading) {
    c.rows_with_leading_le.assign(n, 0);
    for (int k = 0; k < n; ++k) {
      c.rows_with_leading_le[k] = static_cast<int>(std::count_if(leading->begin(), leading->end(), [k](int l) { return l <= k; }));
    }
  }
  return c;
}

/// Sorted random leading columns in [0, n) for m rows.
std::vector<int> randomLeading(std::mt19937& rng, int m, int n) {
  std::uniform_int_distribution<int> col(0, n - 1);
  std::vector<int> lead(m);
  for (int& l : lead) l = col(rng);
  std::sort(lead.begin(), lead.end());
  return lead;
}

/// Checks one staircaseQrInPlace result against Eigen's QR of the same matrix.
void checkResult(const QrCase& c, const Eigen::MatrixXd& ours, double tol) {
  const int m = static_cast<int>(c.W.rows());
  const int n = c.n;
  const int cols = static_cast<int>(c.W.cols());
  const int steps = std::min(m, n);

  const Eigen::MatrixXd A = c.W.leftCols(n);
  const Eigen::MatrixXd B = c.W.rightCols(cols - n);
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(A);
  const Eigen::MatrixXd R_eigen = qr.matrixQR().topRows(steps).triangularView<Eigen::Upper>();
  const Eigen::MatrixXd QtB_eigen =
      cols > n ? Eigen::MatrixXd(qr.householderQ().transpose() * B) : Eigen::MatrixXd(m, 0);

  const Eigen::MatrixXd R_ours = ours.topLeftCorner(steps, n);
  const Eigen::MatrixXd QtB_ours = ours.rightCols(cols - n);
  const double scale = std::max(1.0, c.W.cwiseAbs().maxCoeff() * c.W.cwiseAbs().maxCoeff() * m);

  // Upper triangular: nothing left below the diagonal of the eliminated columns.
  for (int j = 0; j < n; ++j) {
    for (int i = j + 1; i < m; ++i) EXPECT_EQ(ours(i, j), 0.0) << "below the diagonal at (" << i << "," << j << ")";
  }
  // R^T R = A^T A (and equal to Eigen's).
  EXPECT_LT((R_ours.transpose() * R_ours - A.transpose() * A).cwiseAbs().maxCoeff(), tol * scale);
  EXPECT_LT((R_ours.transpose() * R_ours - R_eigen.transpose() * R_eigen).cwiseAbs().maxCoeff(), tol * scale);
  // R^T (Q^T B) = A^T B (and equal to Eigen's); nothing to compare without a right-hand side.
  if (cols > n) {
    EXPECT_LT((R_ours.transpose() * QtB_ours.topRows(steps) - A.transpose() * B).cwiseAbs().maxCoeff(), tol * scale);
    EXPECT_LT((R_ours.transpose() * QtB_ours.topRows(steps) - R_eigen.transpose() * QtB_eigen.topRows(steps))
                  .cwiseAbs().maxCoeff(),
              tol * scale);
  }
  // Q orthogonal: column norms of B preserved, so the residual rows carry the
  // rest (rows below n: what no column explains; same norm as Eigen's).
  for (int j = 0; j < cols - n; ++j) {
    EXPECT_NEAR(QtB_ours.col(j).norm(), B.col(j).norm(), tol * std::max(1.0, B.col(j).norm()));
    if (m > n) {
      EXPECT_NEAR(QtB_ours.col(j).tail(m - n).norm(), QtB_eigen.col(j).tail(m - n).norm(),
                  tol * std::max(1.0, B.col(j).norm()));
    }
  }
}

/// Runs staircaseQrInPlace on copies in both layouts (the smoother uses the
/// row-major one) and checks each against Eigen's QR of the same matrix.
void checkAgainstEigen(const QrCase& c, double tol = 1e-10) {
  const int m = static_cast<int>(c.W.rows());
  const int cols = static_cast<int>(c.W.cols());
  Eigen::MatrixXd col_major = c.W;
  RowMajorMatrixXd row_major = c.W;
  Eigen::VectorXd workspace(m + cols);
  const int* staircase = c.rows_with_leading_le.empty() ? nullptr : c.rows_with_leading_le.data();
  staircaseQrInPlace(col_major, c.n, staircase, workspace.data());
  staircaseQrInPlace(row_major, c.n, staircase, workspace.data());
  // Not compared entry by entry: where a pivot is ~0 the two layouts' rounding
  // can pick opposite Householder signs (R is unique only up to row signs);
  // each is checked against Eigen below with sign-invariant tests.
  const Eigen::MatrixXd row_major_result = row_major;
  {
    SCOPED_TRACE("column-major");
    checkResult(c, col_major, tol);
  }
  SCOPED_TRACE("row-major");
  checkResult(c, row_major_result, tol);
}

TEST(StaircaseQr, DenseRandomMatchesEigen) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 40; ++trial) {
    std::uniform_int_distribution<int> dim(1, 14);
    const int n = dim(rng);
    const int m = n + dim(rng) - 1;  // m >= n
    const QrCase c = makeCase(rng, m, n, 1);
    SCOPED_TRACE(::testing::Message() << "trial " << trial << " m=" << m << " n=" << n);
    checkAgainstEigen(c);
  }
}

TEST(StaircaseQr, StaircaseStructuredMatchesEigen) {
  std::mt19937 rng(12);
  for (int trial = 0; trial < 60; ++trial) {
    std::uniform_int_distribution<int> dim(2, 16);
    const int n = dim(rng);
    const int m = n + dim(rng);
    const std::vector<int> lead = randomLeading(rng, m, n);
    // Sparse rows: the leading column is only a lower bound of the first nonzero.
    const QrCase c = makeCase(rng, m, n, 1, &lead, trial % 2 ? 0.6 : 1.0);
    SCOPED_TRACE(::testing::Message() << "trial " << trial << " m=" << m << " n=" << n);
    checkAgainstEigen(c);
  }
}

TEST(StaircaseQr, StaircaseGivenAsDenseGivesTheSameFactor) {
  // The staircase hint only skips rows that are zero: the result must be the
  // same as the dense call up to rounding (same reflections, same signs).
  std::mt19937 rng(13);
  const int m = 20, n = 12;
  const std::vector<int> lead = randomLeading(rng, m, n);
  const QrCase c = makeCase(rng, m, n, 2, &lead);
  Eigen::MatrixXd staircase = c.W, dense = c.W;
  Eigen::VectorXd workspace(c.W.cols());
  staircaseQrInPlace(staircase, n, c.rows_with_leading_le.data(), workspace.data());
  staircaseQrInPlace(dense, n, nullptr, workspace.data());
  const Eigen::MatrixXd Rs = staircase.topRows(n), Rd = dense.topRows(n);
  EXPECT_LT((Rs.transpose() * Rs - Rd.transpose() * Rd).cwiseAbs().maxCoeff(), 1e-10 * m);
}

TEST(StaircaseQr, StructurallyEmptyColumns) {
  // Columns that no row touches (a variable whose rows all sit elsewhere), in
  // the middle and at the end; rows_with_leading_le[k] < k + 1 there, so the
  // diagonal row of such a column starts later.
  std::mt19937 rng(14);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 9;
    const int m = 14;
    std::vector<int> lead = randomLeading(rng, m, n);
    const int empty = 2 + trial % 5;  // a column with nothing in it
    QrCase c = makeCase(rng, m, n, 1, &lead);
    c.W.col(empty).setZero();
    if (trial % 3 == 0) c.W.col(n - 1).setZero();
    SCOPED_TRACE(::testing::Message() << "trial " << trial << " empty column " << empty);
    checkAgainstEigen(c);
  }
  // Rows that all start late: leading column 3 for every row, columns 0-2 empty.
  std::vector<int> late(10, 3);
  const QrCase c = makeCase(rng, 10, 6, 1, &late);
  checkAgainstEigen(c);
  Eigen::MatrixXd W = c.W;
  Eigen::VectorXd workspace(W.cols());
  staircaseQrInPlace(W, 6, c.rows_with_leading_le.data(), workspace.data());
  for (int k = 0; k < 3; ++k) EXPECT_EQ(W(k, k), 0.0) << "column " << k << " is empty: its pivot must be exactly 0";
}

TEST(StaircaseQr, FewerRowsThanColumns) {
  std::mt19937 rng(15);
  for (int trial = 0; trial < 20; ++trial) {
    const int n = 10;
    const int m = 1 + trial % 9;  // m < n
    const QrCase dense = makeCase(rng, m, n, 1);
    SCOPED_TRACE(::testing::Message() << "dense m=" << m);
    checkAgainstEigen(dense);
    const std::vector<int> lead = randomLeading(rng, m, n);
    const QrCase stair = makeCase(rng, m, n, 1, &lead);
    SCOPED_TRACE("staircase");
    checkAgainstEigen(stair);
  }
}

TEST(StaircaseQr, SeveralRightHandSides) {
  std::mt19937 rng(16);
  for (int extra : {0, 1, 3, 7}) {
    const int m = 15, n = 8;
    const std::vector<int> lead = randomLeading(rng, m, n);
    const QrCase c = makeCase(rng, m, n, extra, &lead);
    SCOPED_TRACE(::testing::Message() << "extra columns " << extra);
    checkAgainstEigen(c);
  }
}

TEST(StaircaseQr, LeastSquaresSolutionMatches) {
  // The reason for the QR: R x = (Q^T b).head(n) solves min |A x - b|.
  std::mt19937 rng(17);
  const int m = 30, n = 12;
  const std::vector<int> lead = randomLeading(rng, m, n);
  // Ensure full column rank: every column is some row's leading column.
  std::vector<int> full = lead;
  for (int k = 0; k < n; ++k) full[k] = k;
  std::sort(full.begin(), full.end());
  const QrCase c = makeCase(rng, m, n, 1, &full);
  Eigen::MatrixXd W = c.W;
  Eigen::VectorXd workspace(W.cols());
  staircaseQrInPlace(W, n, c.rows_with_leading_le.data(), workspace.data());
  const Eigen::VectorXd x = W.topLeftCorner(n, n).triangularView<Eigen::Upper>().solve(W.col(n).head(n));
  const Eigen::VectorXd x_ref = c.W.leftCols(n).colPivHouseholderQr().solve(c.W.col(n));
  EXPECT_LT((x - x_ref).cwiseAbs().maxCoeff(), 1e-9 * std::max(1.0, x_ref.cwiseAbs().maxCoeff()));
  // The residual rows hold exactly the least-squares residual norm.
  EXPECT_NEAR(W.col(n).tail(m - n).norm(), (c.W.leftCols(n) * x_ref - c.W.col(n)).norm(), 1e-9);
}

TEST(StaircaseQr, WorksOnABlockOfALargerMatrix) {
  // eliminateClique passes the top-left corner of a larger scratch matrix.
  std::mt19937 rng(18);
  const int m = 9, n = 5;
  const std::vector<int> lead = randomLeading(rng, m, n);
  const QrCase c = makeCase(rng, m, n, 1, &lead);
  Eigen::MatrixXd big = Eigen::MatrixXd::Constant(m + 4, n + 5, 7.0);
  big.topLeftCorner(m, n + 1) = c.W;
  Eigen::VectorXd workspace(n + 1);
  staircaseQrInPlace(big.topLeftCorner(m, n + 1), n, c.rows_with_leading_le.data(), workspace.data());
  Eigen::MatrixXd alone = c.W;
  staircaseQrInPlace(alone, n, c.rows_with_leading_le.data(), workspace.data());
  EXPECT_LT((big.topLeftCorner(m, n + 1) - alone).cwiseAbs().maxCoeff(), 1e-14);
  // Outside the block nothing changed.
  EXPECT_TRUE((big.rightCols(4).array() == 7.0).all());
  EXPECT_TRUE((big.bottomRows(4).array() == 7.0).all());
}

}  // namespace
}  // namespace rilo
