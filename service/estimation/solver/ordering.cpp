#include "estimation/solver/ordering.h"

#include <ccolamd.h>
#include <colamd.h>

#include <algorithm>
#include <array>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {

namespace {

// One stats/knobs array serves both COLAMD and CCOLAMD.
static_assert(COLAMD_STATS == CCOLAMD_STATS && COLAMD_KNOBS == CCOLAMD_KNOBS);
static_assert(COLAMD_STATUS == CCOLAMD_STATUS);

// Key incidence in compressed column form, as (C)COLAMD wants it: column j is
// keys[j] (ascending), its rows are the factors touching it (ascending).
struct Incidence {
  std::vector<Key> keys;
  std::vector<int> col_ptr;
  std::vector<int> rows;
  int n_rows = 0;
};

template <class KeysOf>
Incidence buildIncidence(std::size_t n_factors, KeysOf keys_of) {
  if (n_factors > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::invalid_argument("ordering: too many factors for 32-bit COLAMD");
  }
  Incidence inc;
  inc.n_rows = static_cast<int>(n_factors);
  std::size_t nnz = 0;
  for (std::size_t f = 0; f < n_factors; ++f) {
    const auto& ks = keys_of(f);
    inc.keys.insert(inc.keys.end(), ks.begin(), ks.end());
    nnz += ks.size();
  }
  std::sort(inc.keys.begin(), inc.keys.end());
  inc.keys.erase(std::unique(inc.keys.begin(), inc.keys.end()), inc.keys.end());
  auto column = [&inc](Key k) {
    return static_cast<std::size_t>(std::lower_bound(inc.keys.begin(), inc.keys.end(), k) - inc.keys.begin());
  };
  // Counting pass then fill pass; rows come out ascending per column.
  inc.col_ptr.assign(inc.keys.size() + 1, 0);
  for (std::size_t f = 0; f < n_factors; ++f) {
    for (Key k : keys_of(f)) ++inc.col_ptr[column(k) + 1];
  }
  for (std::size_t j = 0; j < inc.keys.size(); ++j) inc.col_ptr[j + 1] += inc.col_ptr[j];
  inc.rows.resize(nnz);
  std::vector<int> next(inc.col_ptr.begin(), inc.col_ptr.end() - 1);
  for (std::size_t f = 0; f < n_factors; ++f) {
    for (Key k : keys_of(f)) inc.rows[static_cast<std::size_t>(next[column(k)]++)] = static_cast<int>(f);
  }
  return inc;
}

Incidence incidenceOf(const FactorGraph& graph) {
  return buildIncidence(graph.size(), [&graph](std::size_t f) -> const std::vector<Key>& { return graph[f]->keys(); });
}

Incidence incidenceOf(std::span<const std::vector<Key>> factor_keys) {
  return buildIncidence(factor_keys.size(),
                        [factor_keys](std::size_t f) -> const std::vector<Key>& { return factor_keys[f]; });
}

// (C)COLAMD on a column incidence (n_rows rows, columns as given); cmember
// null = unconstrained COLAMD. Returns column indices in elimination order.
std::vector<int> orderColumns(int n_rows, std::span<const int> col_ptr_in, std::span<const int> rows,
                              const int* cmember) {
  const int n_col = static_cast<int>(col_ptr_in.size()) - 1;
  if (n_col <= 0) return {};
  const int nnz = col_ptr_in.back();
  const std::size_t a_len =
      cmember ? ccolamd_recommended(nnz, n_rows, n_col) : colamd_recommended(nnz, n_rows, n_col);
  if (a_len == 0 || a_len > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    throw std::runtime_error("ordering: problem too large for 32-bit COLAMD");
  }
  // (C)COLAMD overwrite A and p: work on copies.
  std::vector<int> A(a_len, 0);
  std::copy(rows.begin(), rows.begin() + nnz, A.begin());
  std::vector<int> p(col_ptr_in.begin(), col_ptr_in.end());
  std::array<int, CCOLAMD_STATS> stats{};
  std::array<double, CCOLAMD_KNOBS> knobs{};
  bool ok;
  if (cmember) {
    ccolamd_set_defaults(knobs.data());
    // No dense row/column heuristics (as GTSAM): the order then depends only
    // on the structure, and dense keys (anchors) are still ordered by degree.
    knobs[CCOLAMD_DENSE_ROW] = -1;
    knobs[CCOLAMD_DENSE_COL] = -1;
    std::vector<int> cm(cmember, cmember + n_col);  // ccolamd takes a non-const array
    ok = ccolamd(n_rows, n_col, static_cast<int>(a_len), A.data(), p.data(), knobs.data(), stats.data(), cm.data()) !=
         0;
  } else {
    colamd_set_defaults(knobs.data());
    knobs[COLAMD_DENSE_ROW] = -1;
    knobs[COLAMD_DENSE_COL] = -1;
    ok = colamd(n_rows, n_col, static_cast<int>(a_len), A.data(), p.data(), knobs.data(), stats.data()) != 0;
  }
  if (!ok) {
    throw std::runtime_error(std::string(cmember ? "ccolamd" : "colamd") + " failed with status " +
                             std::to_string(stats[COLAMD_STATUS]));
  }
  p.resize(static_cast<std::size_t>(n_col));
  return p;
}

std::vector<Key> orderIncidence(const Incidence& inc, const int* cmember) {
  const std::vector<int> columns = orderColumns(inc.n_rows, inc.col_ptr, inc.rows, cmember);
  std::vector<Key> order(columns.size());
  for (std::size_t i = 0; i < columns.size(); ++i) order[i] = inc.keys[static_cast<std::size_t>(columns[i])];
  return order;
}

// Replaces each group by its rank among the distinct groups (CCOLAMD wants
// sets in 0..n_col-1).
void rankGroups(std::vector<int>& groups) {
  std::vector<int> distinct(groups);
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  for (int& g : groups) g = static_cast<int>(std::lower_bound(distinct.begin(), distinct.end(), g) - distinct.begin());
}

std::vector<Key> constrained(const Incidence& inc, const OrderingConstraints& constraints) {
  if (constraints.default_group < 0) throw std::invalid_argument("OrderingConstraints: default_group is negative");
  std::vector<int> groups(inc.keys.size());
  for (std::size_t j = 0; j < inc.keys.size(); ++j) {
    auto it = constraints.group.find(inc.keys[j]);
    const int g = it == constraints.group.end() ? constraints.default_group : it->second;
    if (g < 0) throw std::invalid_argument("OrderingConstraints: negative group for key " + keyString(inc.keys[j]));
    groups[j] = g;
  }
  rankGroups(groups);
  return orderIncidence(inc, groups.data());
}

}  // namespace

OrderingConstraints OrderingConstraints::firstAndLast(std::span<const Key> first, std::span<const Key> last) {
  OrderingConstraints c;
  c.default_group = 1;
  for (Key k : first) c.group[k] = 0;
  for (Key k : last) c.group[k] = 2;
  return c;
}

std::vector<Key> naturalOrdering(const FactorGraph& graph) { return incidenceOf(graph).keys; }

std::vector<Key> colamdOrdering(const FactorGraph& graph) { return orderIncidence(incidenceOf(graph), nullptr); }

std::vector<Key> colamdOrdering(std::span<const std::vector<Key>> factor_keys) {
  return orderIncidence(incidenceOf(factor_keys), nullptr);
}

std::vector<Key> constrainedOrdering(const FactorGraph& graph, const OrderingConstraints& constraints) {
  return constrained(incidenceOf(graph), constraints);
}

std::vector<Key> constrainedOrdering(std::span<const std::vector<Key>> factor_keys,
                                     const OrderingConstraints& constraints) {
  return constrained(incidenceOf(factor_keys), constraints);
}

std::vector<int> constrainedColumnOrdering(int n_rows, std::span<const int> col_ptr, std::span<const int> rows,
                                           std::vector<int> groups) {
  if (col_ptr.empty() || groups.size() + 1 != col_ptr.size()) {
    throw std::invalid_argument("constrainedColumnOrdering: groups must have one entry per column");
  }
  for (int g : groups) {
    if (g < 0) throw std::invalid_argument("constrainedColumnOrdering: negative group");
  }
  rankGroups(groups);
  return orderColumns(n_rows, col_ptr, rows, groups.data());
}

}  // namespace rilo
