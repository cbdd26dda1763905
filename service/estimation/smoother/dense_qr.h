#pragma once
// In-place Householder QR of a clique's stacked linear system [A | b], with
// rows sorted by their first nonzero column ("staircase"): the reflection of
// column k only spans the rows that can be nonzero there, so the sparse
// factor rows of a clique cost little more than their own size.
//
// Square-root (QR) elimination rather than Cholesky on A^T A: the IMU
// factors' square-root information reaches 1e6 while range rows are ~10, and
// forming A^T A would square that conditioning.
#include <Eigen/Core>

namespace rilo {

/// Row-major dynamic matrix: the layout of the smoother's stacked systems.
using RowMajorMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Eliminates the first `n` columns of W (m x (n + extra)); the remaining
/// columns (right-hand sides) are transformed by the same reflections.
/// `rows_with_leading_le[k]` is the number of leading rows of W whose first
/// nonzero column is <= k (nondecreasing in k, rows sorted accordingly);
/// pass nullptr for a dense W. On return the first min(m, n) rows hold
/// [R | Q^T b] (zeros below the diagonal); rows below n hold the part of Q^T b
/// no column can explain (the residual). `workspace` needs W.rows() + W.cols()
/// doubles.
///
/// Row-major is the fast layout: applying a reflection is two contiguous
/// axpy sweeps along the rows it spans (s = tau (w_k + sum_i v_i w_i), then
/// w_k -= s, w_i -= v_i s), which vectorize without reordering any sum.
void staircaseQrInPlace(Eigen::Ref<RowMajorMatrixXd> W, int n, const int* rows_with_leading_le, double* workspace);
/// Same for a column-major W (Eigen's Householder kernels; the reference the
/// tests compare the row-major kernel with).
void staircaseQrInPlace(Eigen::Ref<Eigen::MatrixXd> W, int n, const int* rows_with_leading_le, double* workspace);

}  // namespace rilo
