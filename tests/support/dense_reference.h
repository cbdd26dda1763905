#pragma once
// Dense reference solutions for smoother tests: the whitened (IRLS-weighted)
// Jacobian of a whole graph at a linearization point, solved by
// column-pivoting Householder QR (backward stable, no normal equations).
#include <Eigen/Dense>
#include <unordered_map>
#include <vector>

#include "estimation/graph/factor.h"
#include "estimation/smoother/linear_marginal.h"

namespace rilo::testing {

struct DenseLinearSystem {
  std::vector<Key> keys;                  ///< column blocks, sorted
  std::unordered_map<Key, int> offset;    ///< column offset of each key
  Eigen::MatrixXd A;                      ///< whitened Jacobian
  Eigen::VectorXd b;                      ///< -r: solve min |A x - b|
};

inline DenseLinearSystem linearizeDense(const FactorGraph& graph, const std::vector<LinearMarginalPtr>& marginals,
                                        const Values& theta) {
  DenseLinearSystem s;
  std::vector<Key> keys;
  for (const auto& f : graph) keys.insert(keys.end(), f->keys().begin(), f->keys().end());
  for (const auto& m : marginals) keys.insert(keys.end(), m->keys().begin(), m->keys().end());
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  int cols = 0;
  for (Key k : keys) {
    s.offset[k] = cols;
    cols += theta.dim(k);
  }
  int rows = 0;
  for (const auto& f : graph) rows += f->dim();
  for (const auto& m : marginals) rows += m->rows();
  s.keys = keys;
  s.A = Eigen::MatrixXd::Zero(rows, cols);
  s.b = Eigen::VectorXd::Zero(rows);
  int row = 0;
  for (const auto& f : graph) {
    Residual r;
    Jacobians H;
    f->linearize(theta, r, H);
    for (std::size_t k = 0; k < f->keys().size(); ++k) {
      s.A.block(row, s.offset.at(f->keys()[k]), f->dim(), H[k].cols()) = H[k];
    }
    s.b.segment(row, f->dim()) = -r;
    row += f->dim();
  }
  for (const auto& m : marginals) {
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    m->evaluate(theta, r, &J);
    int c = 0;
    for (Key k : m->keys()) {
      const int dim = theta.dim(k);
      s.A.block(row, s.offset.at(k), m->rows(), dim) = J.middleCols(c, dim);
      c += dim;
    }
    s.b.segment(row, m->rows()) = -r;
    row += m->rows();
  }
  return s;
}

/// Least-squares step of every key.
inline std::unordered_map<Key, Eigen::VectorXd> solveDense(const DenseLinearSystem& s) {
  const Eigen::VectorXd x = s.A.colPivHouseholderQr().solve(s.b);
  std::unordered_map<Key, Eigen::VectorXd> out;
  for (std::size_t i = 0; i < s.keys.size(); ++i) {
    const int begin = s.offset.at(s.keys[i]);
    const int end = i + 1 < s.keys.size() ? s.offset.at(s.keys[i + 1]) : static_cast<int>(x.size());
    out[s.keys[i]] = x.segment(begin, end - begin);
  }
  return out;
}

}  // namespace rilo::testing
