#include "estimation/smoother/dense_qr.h"

#include <Eigen/Householder>
#include <algorithm>
#include <cmath>
#include <limits>

namespace rilo {

// The clique QR is ~25% of a replay and its reflection sweeps are plain
// elementwise loops: on x86-64 Linux the function is also compiled for AVX2
// (4-wide instead of SSE2's 2-wide) and picked at load time when the CPU has
// it. Without FMA (not part of "avx2") every element sees the same
// operations in the same order, so both versions give bit-identical results.
// Not in sanitizer builds: the loader runs the version's resolver (an
// ifunc) while relocating, before the sanitizer's runtime is up, and its
// instrumentation crashed every ThreadSanitizer binary at start.
#if defined(__x86_64__) && defined(__linux__) && defined(__GNUC__) && !defined(RILO_NO_TARGET_CLONES)
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
  // The reference layout (tests compare the two); Eigen's reflections.
  const int m = static_cast<int>(W.rows());
  const int cols = static_cast<int>(W.cols());
  const int steps = std::min(m, n);
  for (int k = 0; k < steps; ++k) {
    const int end = rows_with_leading_le ? std::max(k + 1, std::min(m, rows_with_leading_le[k])) : m;
    const int length = end - k;
    if (length > 1) {
      double tau = 0.0;
      double beta = 0.0;
      auto column = W.col(k).segment(k, length);
      column.makeHouseholderInPlace(tau, beta);
      if (cols > k + 1) {
        W.block(k, k + 1, length, cols - k - 1).applyHouseholderOnTheLeft(column.tail(length - 1), tau, workspace);
      }
      W(k, k) = beta;
      column.tail(length - 1).setZero();
    }
  }
}

}  // namespace rilo
