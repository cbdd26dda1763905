#pragma once
// Nonlinear factor: a whitened residual r(x) over a few variables, its
// Jacobians in the retraction chart of each variable, and an optional robust
// loss. Buffers are fixed-capacity Eigen types: evaluating a factor never
// allocates.
#include <array>
#include <memory>
#include <vector>

#include "estimation/graph/values.h"
#include "estimation/noise/robust_loss.h"

namespace rilo {

constexpr int kMaxResidualDim = 15;  ///< combined IMU factor
constexpr int kMaxVarDim = 6;        ///< Pose3, ImuBias
constexpr int kMaxFactorKeys = 6;    ///< combined IMU factor: x_i v_i b_i x_j v_j b_j

/// Covariance of one variable, in its tangent chart.
using CovarianceBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxVarDim, kMaxVarDim>;

using Residual = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxResidualDim, 1>;
using JacobianBlock = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxResidualDim, kMaxVarDim>;
/// One Jacobian block per key of the factor, in keys() order.
using Jacobians = std::array<JacobianBlock, kMaxFactorKeys>;

class Factor {
 public:
  /// Throws std::invalid_argument on 0 or too many keys. (dim() is virtual, so subclasses with
  /// vector residuals reject asymmetric losses in their own constructors.)
  Factor(std::vector<Key> keys, RobustLossPtr loss = nullptr);
  virtual ~Factor() = default;
  Factor(const Factor&) = delete;
  Factor& operator=(const Factor&) = delete;

  const std::vector<Key>& keys() const { return keys_; }
  /// Residual dimension.
  virtual int dim() const = 0;

  /// Whitened residual r = sqrt_info * e(x) (sqrt_info is any square root of
  /// the information: the IMU factors use a lower-triangular L^-1, the priors an
  /// upper-triangular U; only r and H are contractual) and, when H is not null, the
  /// whitened Jacobians H[k] = d r / d delta_k (dim() x dim(key k)).
  virtual void evaluate(const Values& x, Residual& r, Jacobians* H) const = 0;

  /// A motion prior (height band and hold, vertical speed, zero velocity):
  /// what a walker's body allows, not a measurement. D-iSAM2 damps the new
  /// variables when new measurements disagree with the prediction; a motion
  /// prior's pull does not count (d_isam2_step.cpp).
  void markMotionPrior() { motion_prior_ = true; }
  bool isMotionPrior() const { return motion_prior_; }

  const RobustLoss* loss() const { return loss_.get(); }
  const RobustLossPtr& lossPtr() const { return loss_; }

  /// Nonlinear error: |r|^2/2 without a loss; rho(r) for a scalar residual
  /// (signed); rho(|r|) for a vector residual (symmetric losses only).
  double error(const Values& x) const;
  /// Error of an already evaluated whitened residual (same rules as error()).
  double errorOfResidual(const Residual& r) const;

  /// IRLS linearization at x: r and H scaled by sqrt(w), w = loss weight at
  /// the current residual (1 without a loss). Returns w.
  double linearize(const Values& x, Residual& r, Jacobians& H) const;

 private:
  std::vector<Key> keys_;
  RobustLossPtr loss_;
  bool motion_prior_ = false;
};

using FactorPtr = std::shared_ptr<const Factor>;

/// A nonlinear factor graph: an ordered list of factors.
class FactorGraph {
 public:
  void add(FactorPtr f) { factors_.push_back(std::move(f)); }
  template <class F, class... Args>
  void emplace(Args&&... args) { factors_.push_back(std::make_shared<F>(std::forward<Args>(args)...)); }
  std::size_t size() const { return factors_.size(); }
  const FactorPtr& operator[](std::size_t i) const { return factors_[i]; }
  auto begin() const { return factors_.begin(); }
  auto end() const { return factors_.end(); }
  /// Sum of factor errors at x.
  double error(const Values& x) const;

 private:
  std::vector<FactorPtr> factors_;
};

}  // namespace rilo
