#include "estimation/smoother/dense_qr.h"

#include <Eigen/Householder>
#include <algorithm>

namespace rilo {

void staircaseQrInPlace(Eigen::Ref<Eigen::MatrixXd> W, int n, const int* rows_with_leading_le, double* workspace) {
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
