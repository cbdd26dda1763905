#pragma once
// Gauss-Newton normal equations of a factor graph, assembled block-sparse.
//
// Factor::linearize gives, per factor, the robust-weighted whitened residual
// r_f and Jacobian blocks H_f,k. The linearized problem is
//   min_d  sum_f |sum_k H_f,k d_k + r_f|^2,
// so with J stacking all blocks: Hessian H = J^T J, gradient g = J^T r, and
// the Gauss-Newton step solves H d = -g.
//
// H is stored as the upper triangle of a scalar CSC matrix whose columns
// follow a key ordering (the elimination order): variable blocks are expanded
// to their tangent dimension, so variable b occupies columns
// [offset(b), offset(b) + dim(b)). The pattern (and, per factor, where each
// of its blocks lands) is computed once in setStructure(); linearize() only
// overwrites values, so iterations never reallocate.
#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "estimation/graph/factor.h"
#include "estimation/solver/cholmod_context.h"

namespace rilo {

class NormalEquations {
 public:
  /// Lays out the variables of `ordering` (elimination order; may contain keys
  /// no factor touches) and the sparsity pattern of `graph`. Variable
  /// dimensions come from `values`. Throws std::invalid_argument if a factor
  /// key is missing from `ordering` or `values`, a factor repeats a key, or
  /// `ordering` repeats a key; the object is then left empty.
  void setStructure(const FactorGraph& graph, const Values& values, std::span<const Key> ordering);

  /// Linearizes every factor of `graph` (the graph given to setStructure, or
  /// one with identical factor keys in the same order) at x and fills H and g
  /// in place. No allocation. Throws std::invalid_argument if the graph size
  /// differs and std::logic_error if a factor returns blocks of the wrong size.
  void linearize(const FactorGraph& graph, const Values& x);

  /// Scalar dimension (sum of variable dimensions).
  int dim() const { return n_; }
  std::size_t numVariables() const { return ordering_.size(); }
  /// Keys in column order.
  const std::vector<Key>& ordering() const { return ordering_; }
  /// Block position of a key; throws std::out_of_range if absent.
  std::size_t position(Key k) const;
  int offset(std::size_t pos) const { return offsets_[pos]; }
  int varDim(std::size_t pos) const { return offsets_[pos + 1] - offsets_[pos]; }

  /// H (upper triangle, CSC). Valid while this object lives and the structure
  /// is unchanged.
  SymmetricCscView hessian() const { return {n_, col_ptr_.data(), row_idx_.data(), values_.data()}; }
  /// Mutable values of H (e.g. to add damping on the diagonal).
  std::span<double> hessianValues() { return values_; }
  /// Index into hessianValues() of each diagonal entry H_ii.
  const std::vector<int>& diagonalIndex() const { return diag_idx_; }
  /// g = J^T r.
  const Eigen::VectorXd& gradient() const { return gradient_; }
  /// y = H x with the symmetric matrix represented by the stored upper
  /// triangle (current values, including any damping added by the caller).
  void multiplyHessian(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;

  /// Number of stored entries of the upper triangle.
  int nonzeros() const { return n_ > 0 ? col_ptr_.back() : 0; }

 private:
  // One Hessian block contributed by a factor: keys (i, j) of the factor with
  // pos(i) <= pos(j); the block lands in the columns of key j starting at
  // entry col_ptr[col] + row_start of each column.
  struct BlockSlot {
    std::uint8_t i;
    std::uint8_t j;
    int row_start;
  };

  void buildStructure(const FactorGraph& graph, const Values& values, std::span<const Key> ordering);
  void clear();

  int n_ = 0;
  std::vector<Key> ordering_;
  std::unordered_map<Key, std::size_t> position_;
  std::vector<int> offsets_{0};  // numVariables() + 1
  std::vector<int> col_ptr_{0};  // n_ + 1
  std::vector<int> row_idx_;
  std::vector<double> values_;
  std::vector<int> diag_idx_;
  Eigen::VectorXd gradient_;
  // Per factor: positions of its keys, and its block slots (flattened).
  std::vector<std::size_t> factor_key_begin_{0};  // size()+1 into factor_pos_
  std::vector<std::size_t> factor_pos_;
  std::vector<std::size_t> factor_slot_begin_{0};  // size()+1 into slots_
  std::vector<BlockSlot> slots_;
  // Linearization buffers (fixed capacity: no allocation per factor).
  Residual r_;
  Jacobians H_;
};

}  // namespace rilo
