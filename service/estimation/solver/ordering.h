#pragma once
// Fill-reducing elimination orderings of variables (keys), computed on the
// variable-level (block) structure rather than on scalar columns.
//
// The key incidence is the matrix with one row per factor and one column per
// key; COLAMD orders its columns to reduce fill in the Cholesky factor of
// A^T A, whose pattern is the key adjacency, i.e. the block pattern of the
// Gauss-Newton Hessian. CCOLAMD does the same under constraint groups:
// every key of group g is eliminated before any key of group g + 1 (GTSAM's
// constrained COLAMD): the incremental smoother puts keys to marginalize in
// the first group and the newest keys in the last.
//
// Independent of any solver. All functions are deterministic (same input,
// same order) and return keys in elimination order (first eliminated first).
// Keys that appear in no factor are not ordered. Failures of (C)COLAMD on
// the inputs built here (only out of memory) throw std::runtime_error.
#include <span>
#include <unordered_map>
#include <vector>

#include "estimation/graph/factor.h"
#include "estimation/graph/key.h"

namespace rilo {

/// Constraint groups for constrainedOrdering(): a key of group g is
/// eliminated before every key of a group > g. Keys not listed belong to
/// default_group. Groups must be >= 0; they need not be contiguous.
struct OrderingConstraints {
  std::unordered_map<Key, int> group;
  int default_group = 0;

  /// Three groups: `first` (0), every other key (1), `last` (2).
  static OrderingConstraints firstAndLast(std::span<const Key> first, std::span<const Key> last);
};

/// Keys of the graph's factors sorted ascending (no fill reduction).
std::vector<Key> naturalOrdering(const FactorGraph& graph);

/// COLAMD ordering of the key incidence of `graph`.
std::vector<Key> colamdOrdering(const FactorGraph& graph);
/// Same, from explicit key lists (one per factor).
std::vector<Key> colamdOrdering(std::span<const std::vector<Key>> factor_keys);

/// CCOLAMD ordering with constraint groups. Throws std::invalid_argument for a
/// negative group.
std::vector<Key> constrainedOrdering(const FactorGraph& graph, const OrderingConstraints& constraints);
std::vector<Key> constrainedOrdering(std::span<const std::vector<Key>> factor_keys,
                                     const OrderingConstraints& constraints);

/// The same CCOLAMD ordering on an incidence the caller built: column j
/// (a variable) holds the ascending rows (factors) rows[col_ptr[j] ..
/// col_ptr[j+1]) and belongs to constraint group groups[j] (>= 0). Returns
/// column indices in elimination order. With the columns in ascending key
/// order and the rows in factor order this is exactly constrainedOrdering()
/// (no key lists, maps or searches: for callers that order often).
std::vector<int> constrainedColumnOrdering(int n_rows, std::span<const int> col_ptr, std::span<const int> rows,
                                           std::vector<int> groups);

}  // namespace rilo
