#include "estimation/smoother/dense_qr.h"

#include <Eigen/Householder>
#include <algorithm>
#include <cmath>
#include <limits>

namespace rilo {

namespace {

// Applies H = I - tau [1; v] [1; v]^T to rows [k, k + length) of columns
// [first, cols) of the column-major W: per column, s = tau (w_k + v . w_tail),
// then w_k -= s, w_tail -= s v. One pass over each column segment, which is
// contiguous; Eigen's applyHouseholderOnTheLeft does the same in a gemv and a
// rank-1 update over Block expressions, whose per-column overhead dominated
// the clique QR (segments are a few rows long in a staircase).
// Four columns at a time for instruction-level parallelism.
void applyReflector(double* W, Eigen::Index ld, int k, int length, int first, int cols, const double* v, double tau) {
  const int tail = length - 1;
  int j = first;
  for (; j + 4 <= cols; j += 4) {
    double* c0 = W + static_cast<Eigen::Index>(j) * ld + k;
    double* c1 = c0 + ld;
    double* c2 = c1 + ld;
    double* c3 = c2 + ld;
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    for (int i = 0; i < tail; ++i) {
      s0 += v[i] * c0[i + 1];
      s1 += v[i] * c1[i + 1];
      s2 += v[i] * c2[i + 1];
      s3 += v[i] * c3[i + 1];
    }
    s0 = tau * (s0 + c0[0]);
    s1 = tau * (s1 + c1[0]);
    s2 = tau * (s2 + c2[0]);
    s3 = tau * (s3 + c3[0]);
    c0[0] -= s0;
    c1[0] -= s1;
    c2[0] -= s2;
    c3[0] -= s3;
    for (int i = 0; i < tail; ++i) {
      c0[i + 1] -= s0 * v[i];
      c1[i + 1] -= s1 * v[i];
      c2[i + 1] -= s2 * v[i];
      c3[i + 1] -= s3 * v[i];
    }
  }
  for (; j < cols; ++j) {
    double* c = W + static_cast<Eigen::Index>(j) * ld + k;
    double s = 0.0;
    for (int i = 0; i < tail; ++i) s += v[i] * c[i + 1];
    s = tau * (s + c[0]);
    c[0] -= s;
    for (int i = 0; i < tail; ++i) c[i + 1] -= s * v[i];
  }
}

}  // namespace

// The clique QR is ~25% of a replay and its reflection sweeps are plain
// elementwise loops: on x86-64 Linux the function is also compiled for AVX2
// (4-wide instead of SSE2's 2-wide) and picked at load time when the CPU has
// it. Without FMA (not part of "avx2") every element sees the same
// operations in the same order, so both versions give bit-identical results.
#if defined(__x86_64__) && defined(__linux__) && defined(__GNUC__)
#define RILO_QR_TARGET_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define RILO_QR_TARGET_CLONES
#endif

RILO_QR_TARGET_CLONES
void staircaseQrInPlace(Eigen::Ref<RowMajorMatrixXd> W, int n, const int* rows_with_leading_le, double* workspace) {
  const int m = static_cast<int>(W.rows());
  const int cols = static_cast<int>(W.cols());
  const int steps = std::min(m, n);
  const Eigen::Index ld = W.outerStride();
  double* data = W.data();
  double* s = workspace;             // cols entries: tau * (w_k + v^T W_tail) over the columns right of k
  double* column_buf = workspace + cols;  // m entries: column k, rows k..end
  for (int k = 0; k < steps; ++k) {
    const int end = rows_with_leading_le ? std::max(k + 1, std::min(m, rows_with_leading_le[k])) : m;
    const int length = end - k;
    if (length <= 1) continue;
    double* pivot_row = data + static_cast<Eigen::Index>(k) * ld;
    // Householder vector of column k, rows k..end (Eigen's
    // makeHouseholderInPlace, fused with gathering the column): H x = beta e_1
    // for H = I - tau [1; v] [1; v]^T, essential part v in column_buf[1..].
    const double c0 = pivot_row[k];
    double tail_sq = 0.0;
    for (int i = 1; i < length; ++i) {
      const double x = pivot_row[static_cast<Eigen::Index>(i) * ld + k];
      column_buf[i] = x;
      tail_sq += x * x;
    }
    double tau = 0.0;
    double beta = c0;
    if (tail_sq > std::numeric_limits<double>::min()) {
      beta = std::sqrt(c0 * c0 + tail_sq);
      if (c0 >= 0.0) beta = -beta;
      const double scale = 1.0 / (c0 - beta);
      for (int i = 1; i < length; ++i) column_buf[i] *= scale;
      tau = (beta - c0) / beta;
    }
    const int first = k + 1;
    const int nc = cols - first;
    if (nc > 0 && tau != 0.0) {
      const double* v = column_buf + 1;
      // Two rows per sweep: s and the shared loads are touched half as often
      // (~15% faster on clique systems than one row per sweep).
      for (int j = 0; j < nc; ++j) s[j] = pivot_row[first + j];
      int i = 1;
      for (; i + 1 < length; i += 2) {
        const double va = v[i - 1], vb = v[i];
        const double* ra = pivot_row + static_cast<Eigen::Index>(i) * ld + first;
        const double* rb = ra + ld;
        for (int j = 0; j < nc; ++j) s[j] += va * ra[j] + vb * rb[j];
      }
      if (i < length) {
        const double vi = v[i - 1];
        const double* row = pivot_row + static_cast<Eigen::Index>(i) * ld + first;
        for (int j = 0; j < nc; ++j) s[j] += vi * row[j];
      }
      for (int j = 0; j < nc; ++j) {
        s[j] *= tau;
        pivot_row[first + j] -= s[j];
      }
      i = 1;
      for (; i + 1 < length; i += 2) {
        const double va = v[i - 1], vb = v[i];
        double* ra = pivot_row + static_cast<Eigen::Index>(i) * ld + first;
        double* rb = ra + ld;
        for (int j = 0; j < nc; ++j) {
          const double sj = s[j];
          ra[j] -= va * sj;
          rb[j] -= vb * sj;
        }
      }
      if (i < length) {
        const double vi = v[i - 1];
        double* row = pivot_row + static_cast<Eigen::Index>(i) * ld + first;
        for (int j = 0; j < nc; ++j) row[j] -= vi * s[j];
      }
    }
    pivot_row[k] = beta;
    for (int i = 1; i < length; ++i) pivot_row[static_cast<Eigen::Index>(i) * ld + k] = 0.0;
  }
}

void staircaseQrInPlace(Eigen::Ref<Eigen::MatrixXd> W, int n, const int* rows_with_leading_le, double* workspace) {
  (void)workspace;  // the column-major kernel needs none
  const int m = static_cast<int>(W.rows());
  const int cols = static_cast<int>(W.cols());
  const int steps = std::min(m, n);
  double* data = W.data();
  const Eigen::Index ld = W.outerStride();
  for (int k = 0; k < steps; ++k) {
    const int end = rows_with_leading_le ? std::max(k + 1, std::min(m, rows_with_leading_le[k])) : m;
    const int length = end - k;
    if (length > 1) {
      double tau = 0.0;
      double beta = 0.0;
      auto column = W.col(k).segment(k, length);
      column.makeHouseholderInPlace(tau, beta);
      if (cols > k + 1 && tau != 0.0) {
        applyReflector(data, ld, k, length, k + 1, cols, column.data() + 1, tau);
      }
      W(k, k) = beta;
      column.tail(length - 1).setZero();
    }
  }
}

}  // namespace rilo
