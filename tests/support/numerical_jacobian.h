#pragma once
// Central-difference Jacobians of a factor's whitened residual, taken in the
// same retraction chart as the analytic ones, and a gtest helper comparing them.
#include <gtest/gtest.h>

#include <cmath>

#include "estimation/graph/factor.h"

namespace rilo::testing {

/// d r / d delta_k by central differences with step h on each tangent coordinate.
inline Eigen::MatrixXd numericalJacobian(const Factor& f, const Values& x, std::size_t k, double h = 1e-6) {
  const Key key = f.keys().at(k);
  const int n = x.dim(key);
  Residual r0;
  f.evaluate(x, r0, nullptr);
  Eigen::MatrixXd J(r0.size(), n);
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix<double, kMaxVarDim, 1> d = Eigen::Matrix<double, kMaxVarDim, 1>::Zero();
    Values xp = x, xm = x;
    d(i) = h;
    xp.retractInPlace(key, d.data());
    d(i) = -h;
    xm.retractInPlace(key, d.data());
    Residual rp, rm;
    f.evaluate(xp, rp, nullptr);
    f.evaluate(xm, rm, nullptr);
    J.col(i) = (rp - rm) / (2.0 * h);
  }
  return J;
}

/// Checks every analytic Jacobian block of f at x against central differences:
/// |J_a - J_n|_max <= rel_tol * max(1, |J_n|_max).
inline ::testing::AssertionResult jacobiansMatch(const Factor& f, const Values& x, double rel_tol = 1e-6,
                                                 double h = 1e-6) {
  Residual r;
  Jacobians H;
  f.evaluate(x, r, &H);
  if (r.size() != f.dim()) return ::testing::AssertionFailure() << "residual size " << r.size() << " != dim " << f.dim();
  for (std::size_t k = 0; k < f.keys().size(); ++k) {
    const Eigen::MatrixXd Jn = numericalJacobian(f, x, k, h);
    if (H[k].rows() != Jn.rows() || H[k].cols() != Jn.cols()) {
      return ::testing::AssertionFailure() << "block " << k << " (" << keyString(f.keys()[k]) << ") is "
                                           << H[k].rows() << "x" << H[k].cols() << ", expected " << Jn.rows()
                                           << "x" << Jn.cols();
    }
    const double scale = std::max(1.0, Jn.cwiseAbs().maxCoeff());
    const double err = (Eigen::MatrixXd(H[k]) - Jn).cwiseAbs().maxCoeff();
    if (!(err <= rel_tol * scale)) {
      return ::testing::AssertionFailure() << "block " << k << " (" << keyString(f.keys()[k]) << "): max error "
                                           << err << " > " << rel_tol * scale << "\nanalytic:\n"
                                           << Eigen::MatrixXd(H[k]) << "\nnumerical:\n" << Jn;
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace rilo::testing
