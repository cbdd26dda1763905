// BayesTreeSmoother: removing the top of the tree, symbolic elimination of
// the removed part into cliques, and dense QR elimination of one clique.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "estimation/smoother/bayes_tree_smoother.h"
#include "estimation/smoother/dense_qr.h"
#include "estimation/solver/ordering.h"

namespace rilo {

void BayesTreeSmoother::updateTree(const std::vector<VarId>& marked, const std::vector<FactorId>& new_factors,
                                   UpdateStats& stats) {
  std::vector<VarId> top_vars;
  std::vector<FactorId> top_factors;
  top_cliques_.clear();  // an update that re-eliminates nothing has no top to damp
  const std::vector<CliqueId> orphans = removeTop(marked, top_vars, top_factors);
  top_factors.insert(top_factors.end(), new_factors.begin(), new_factors.end());
  if (top_vars.empty()) return;

  // Keys of new factors go last (GTSAM's constrained-last on observed keys):
  // the newest state and what it observes end up in the root.
  std::vector<Key> last_keys;
  for (FactorId f : new_factors) {
    for (VarId v : factors_[f].vars) {
      if (!vars_[v].marginalize) last_keys.push_back(vars_[v].key);
    }
  }
  eliminateTop(top_vars, top_factors, orphans, last_keys, stats);
}

std::vector<BayesTreeSmoother::CliqueId> BayesTreeSmoother::removeTop(const std::vector<VarId>& marked,
                                                                     std::vector<VarId>& top_vars,
                                                                     std::vector<FactorId>& top_factors) {
  const std::uint64_t clique_stamp = newStamp();
  const std::uint64_t var_stamp = newStamp();
  std::vector<CliqueId> removed;
  for (VarId v : marked) {
    if (vars_[v].mark == var_stamp) continue;
    if (vars_[v].clique == kNone) {  // new variable
      vars_[v].mark = var_stamp;
      top_vars.push_back(v);
    }
    for (CliqueId c = vars_[v].clique; c != kNone && cliques_[c].mark != clique_stamp; c = cliques_[c].parent) {
      cliques_[c].mark = clique_stamp;
      removed.push_back(c);
    }
  }
  std::vector<CliqueId> orphans;
  for (CliqueId c : removed) {
    Clique& q = cliques_[c];
    for (CliqueId child : q.children) {
      if (cliques_[child].mark != clique_stamp) {
        cliques_[child].parent = kNone;
        orphans.push_back(child);
      }
    }
    for (VarId v : q.frontals) {
      if (vars_[v].mark != var_stamp) {
        vars_[v].mark = var_stamp;
        top_vars.push_back(v);
      }
      vars_[v].clique = kNone;
    }
    for (FactorId f : q.factors) {
      factors_[f].clique = kNone;
      top_factors.push_back(f);
    }
    if (q.parent == kNone) roots_.erase(std::find(roots_.begin(), roots_.end(), c));
    if (params_.method == SmootherParams::Method::kDogleg) addCliqueGradient(c, -1.0);
    freeClique(c);
  }
  return orphans;
}

void BayesTreeSmoother::eliminateTop(const std::vector<VarId>& top_vars, const std::vector<FactorId>& top_factors,
                                     const std::vector<CliqueId>& orphans, const std::vector<Key>& last_keys,
                                     UpdateStats& stats) {
  // 1. Constrained ordering of the top: marginalizable keys first, keys of
  //    new factors last. Items are the top's factors, then the orphans'
  //    separators.
  const int n_items = static_cast<int>(top_factors.size() + orphans.size());
  const int n_factors = static_cast<int>(top_factors.size());
  auto item_vars = [&](int item) -> const std::vector<VarId>& {
    return item < n_factors ? factors_[top_factors[item]].vars : cliques_[orphans[item - n_factors]].separator;
  };
  // Groups: marginalizable keys first (they must become leaves); then timed
  // states oldest first (a newer state eliminated below an older one would
  // block the older one's marginalization); then keys without a time
  // (anchors: observed from every state, so eliminated early they would sink
  // below old states); the keys of new factors last, timed before static.
  std::vector<std::int64_t> times;
  for (VarId v : top_vars) {
    if (vars_[v].has_time) times.push_back(vars_[v].t_ns);
  }
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  const int n_times = static_cast<int>(times.size());
  auto time_rank = [&](VarId v) {
    return static_cast<int>(std::lower_bound(times.begin(), times.end(), vars_[v].t_ns) - times.begin());
  };
  const std::uint64_t last_stamp = newStamp();
  for (Key k : last_keys) vars_[key_to_var_.at(k)].mark = last_stamp;
  // The variable-item incidence as constrainedOrdering() builds it from key
  // lists (columns in ascending key order, rows in item order), built here
  // from the slots directly: same CCOLAMD input, same order.
  const int n = static_cast<int>(top_vars.size());
  std::vector<VarId> column_var(top_vars);
  std::sort(column_var.begin(), column_var.end(), [&](VarId a, VarId b) { return vars_[a].key < vars_[b].key; });
  std::vector<int> groups(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) {
    const VarId v = column_var[j];
    VarSlot& slot = vars_[v];
    slot.pos = j;  // column index until the order is known
    const bool last = slot.mark == last_stamp;
    int group;
    if (slot.marginalize) {
      group = 0;
    } else if (!last) {
      group = slot.has_time ? 1 + time_rank(v) : 1 + n_times;
    } else {
      group = slot.has_time ? 2 + n_times + time_rank(v) : 2 + 2 * n_times;
    }
    groups[static_cast<std::size_t>(j)] = group;
  }
  std::vector<int> col_ptr(static_cast<std::size_t>(n) + 1, 0);
  for (int item = 0; item < n_items; ++item) {
    for (VarId v : item_vars(item)) {
      if (vars_[v].pos < 0) throw std::logic_error("BayesTreeSmoother: a top item holds a variable outside the top");
      ++col_ptr[static_cast<std::size_t>(vars_[v].pos) + 1];
    }
  }
  for (int j = 0; j < n; ++j) {
    if (col_ptr[static_cast<std::size_t>(j) + 1] == 0) {
      throw std::logic_error("BayesTreeSmoother: top variable " + keyString(vars_[column_var[j]].key) +
                             " is in no factor or separator of the top");
    }
    col_ptr[static_cast<std::size_t>(j) + 1] += col_ptr[static_cast<std::size_t>(j)];
  }
  std::vector<int> incidence_rows(static_cast<std::size_t>(col_ptr.back()));
  {
    std::vector<int> next(col_ptr.begin(), col_ptr.end() - 1);
    for (int item = 0; item < n_items; ++item) {
      for (VarId v : item_vars(item)) {
        int& slot = next[static_cast<std::size_t>(vars_[v].pos)];
        incidence_rows[static_cast<std::size_t>(slot++)] = item;
      }
    }
  }
  const std::vector<int> order = constrainedColumnOrdering(n_items, col_ptr, incidence_rows, std::move(groups));
  std::vector<VarId> var_at(n);
  for (int i = 0; i < n; ++i) var_at[i] = column_var[static_cast<std::size_t>(order[static_cast<std::size_t>(i)])];
  for (int i = 0; i < n; ++i) vars_[var_at[i]].pos = i;

  // 2. Bucket factors and orphans by their first-eliminated variable.
  std::vector<std::vector<int>> items_at(n);
  for (int item = 0; item < n_items; ++item) {
    int first = n;
    for (VarId v : item_vars(item)) first = std::min(first, vars_[v].pos);
    items_at[first].push_back(item);
  }

  // 3. Symbolic elimination: separator of every variable, elimination tree.
  std::vector<std::vector<int>> sep(n);
  std::vector<std::vector<int>> etree_children(n);
  std::vector<int> scratch;
  for (int j = 0; j < n; ++j) {
    scratch.clear();
    for (int item : items_at[j]) {
      for (VarId v : item_vars(item)) {
        if (vars_[v].pos != j) scratch.push_back(vars_[v].pos);
      }
    }
    for (int child : etree_children[j]) {
      for (int p : sep[child]) {
        if (p != j) scratch.push_back(p);
      }
    }
    std::sort(scratch.begin(), scratch.end());
    scratch.erase(std::unique(scratch.begin(), scratch.end()), scratch.end());
    sep[j] = scratch;
    if (!scratch.empty()) etree_children[scratch.front()].push_back(j);
  }

  // 4. Cliques: a variable joins its elimination-tree child's clique when the
  //    child's separator is exactly {variable} + the variable's separator.
  std::vector<CliqueId> clique_at(n, kNone);
  std::vector<CliqueId> created;
  for (int j = 0; j < n; ++j) {
    CliqueId into = kNone;
    for (int child : etree_children[j]) {
      if (sep[child].size() == sep[j].size() + 1 && cliques_[clique_at[child]].frontals.back() == var_at[child]) {
        into = clique_at[child];
        break;
      }
    }
    if (into == kNone) {
      into = allocClique();
      created.push_back(into);
    }
    cliques_[into].frontals.push_back(var_at[j]);
    clique_at[j] = into;
  }
  for (CliqueId c : created) {
    Clique& q = cliques_[c];
    const int last = vars_[q.frontals.back()].pos;
    q.frontal_dim = 0;
    for (VarId v : q.frontals) {
      q.frontal_dim += vars_[v].dim;
      vars_[v].clique = c;
    }
    q.separator_dim = 0;
    for (int p : sep[last]) {
      q.separator.push_back(var_at[p]);
      q.separator_dim += vars_[var_at[p]].dim;
    }
    q.replaced = true;
    if (sep[last].empty()) {
      roots_.push_back(c);
    } else {
      q.parent = clique_at[sep[last].front()];
      cliques_[q.parent].children.push_back(c);
    }
  }
  for (int item = 0; item < n_items; ++item) {
    int first = n;
    for (VarId v : item_vars(item)) first = std::min(first, vars_[v].pos);
    const CliqueId c = clique_at[first];
    if (item < n_factors) {
      factors_[top_factors[item]].clique = c;
      cliques_[c].factors.push_back(top_factors[item]);
    } else {
      const CliqueId o = orphans[item - n_factors];
      cliques_[o].parent = c;
      cliques_[c].children.push_back(o);
    }
  }

  // 5. Numeric elimination, children before parents (by last frontal).
  for (FactorId f : top_factors) {
    if (factors_[f].needs_linearization) {
      linearizeFactor(factors_[f]);
      ++stats.factors_linearized;
    }
  }
  std::sort(created.begin(), created.end(), [&](CliqueId a, CliqueId b) {
    return vars_[cliques_[a].frontals.back()].pos < vars_[cliques_[b].frontals.back()].pos;
  });
  const double lambda = params_.method == SmootherParams::Method::kDamped ? lambda_ : 0.0;
  for (CliqueId c : created) eliminateClique(c, lambda, stats);
  top_cliques_ = created;
  stats.cliques_reeliminated += static_cast<int>(created.size());
  stats.variables_reeliminated += n;
  for (int i = 0; i < n; ++i) vars_[var_at[i]].pos = -1;
}

void BayesTreeSmoother::linearizeFactor(FactorSlot& f) {
  int cols = 1;
  for (VarId v : f.vars) cols += vars_[v].dim;
  if (f.nonlinear) {
    Residual r;
    Jacobians H;
    f.nonlinear->linearize(theta_, r, H);
    f.linear.resize(r.size(), cols);
    int col = 0;
    for (std::size_t k = 0; k < f.vars.size(); ++k) {
      const int dim = vars_[f.vars[k]].dim;
      f.linear.middleCols(col, dim) = H[k];
      col += dim;
    }
    f.linear.col(col) = -r;
  } else {
    // Frozen variables: theta is the marginal's linearization point, so this
    // is [A | d]; evaluate() keeps it right in general.
    Eigen::VectorXd r;
    Eigen::MatrixXd J;
    f.marginal->evaluate(theta_, r, &J);
    f.linear.resize(r.size(), cols);
    f.linear.leftCols(cols - 1) = J;
    f.linear.col(cols - 1) = -r;
  }
  // Rotate [A | b] to upper-triangular form (the same least-squares problem:
  // Q^T is orthogonal): eliminateClique then knows each row's first nonzero
  // column, and the staircase QR of a clique skips the zeros below the
  // diagonal of every re-elimination instead of re-triangularizing the dense
  // IMU block each time.
  if (f.linear.rows() > 1) {
    if (qr_workspace_.size() < f.linear.rows() + cols) qr_workspace_.resize(f.linear.rows() + cols);
    staircaseQrInPlace(f.linear, cols - 1, nullptr, qr_workspace_.data());
  }
  f.needs_linearization = false;
}

void BayesTreeSmoother::scatterRows(const RowMajorMatrixXd& blocks, const std::vector<VarId>& vars,
                                    Eigen::Ref<RowMajorMatrixXd> W, int rhs_col, const int* dest, int first_row) const {
  // Both row-major: each variable's segment is a short contiguous copy.
  for (int i = 0; i < blocks.rows(); ++i) {
    double* out = W.data() + static_cast<Eigen::Index>(dest ? dest[i] : first_row + i) * W.outerStride();
    const double* in = blocks.data() + static_cast<Eigen::Index>(i) * blocks.outerStride();
    for (VarId v : vars) {
      const VarSlot& slot = vars_[v];
      double* to = out + slot.col;
      // Fixed sizes for the two variable dimensions: a short std::copy_n
      // became a memmove call per segment.
      if (slot.dim == 6) {
        Eigen::Map<Vec6>{to} = Eigen::Map<const Vec6>{in};
      } else if (slot.dim == 3) {
        Eigen::Map<Vec3>{to} = Eigen::Map<const Vec3>{in};
      } else {
        for (int t = 0; t < slot.dim; ++t) to[t] = in[t];
      }
      in += slot.dim;
    }
    out[rhs_col] = *in;
  }
}

void BayesTreeSmoother::eliminateClique(CliqueId c, double lambda, UpdateStats& stats) {
  Clique& q = cliques_[c];
  int col = 0;
  for (VarId v : q.frontals) {
    vars_[v].col = col;
    col += vars_[v].dim;
  }
  for (VarId v : q.separator) {
    vars_[v].col = col;
    col += vars_[v].dim;
  }
  const int fd = q.frontal_dim;
  const int n = col;

  bool regularize = false;
  // Factor blocks (triangularized by linearizeFactor) and children's messages
  // are upper triangular in their own scalar column order: row i is zero
  // before its i-th scalar column, so its first nonzero in W is at or after
  // the smallest clique column among the scalars >= i. Rows past the last
  // scalar are zero on the left (residual rows): leading n.
  auto appendTriangularLeading = [&](const std::vector<VarId>& block_vars, int block_rows, int& r) {
    int scalars = 0;
    for (VarId v : block_vars) scalars += vars_[v].dim;
    suffix_col_.resize(static_cast<std::size_t>(scalars) + 1);
    suffix_col_[static_cast<std::size_t>(scalars)] = n;
    int s = scalars;
    for (auto it = block_vars.rbegin(); it != block_vars.rend(); ++it) {
      const VarSlot& slot = vars_[*it];
      for (int o = slot.dim - 1; o >= 0; --o, --s) {
        suffix_col_[static_cast<std::size_t>(s) - 1] = std::min(suffix_col_[static_cast<std::size_t>(s)], slot.col + o);
      }
    }
    for (int i = 0; i < block_rows; ++i) {
      row_leading_[r++] = suffix_col_[static_cast<std::size_t>(std::min(i, scalars))];
    }
  };
  for (int attempt = 0; attempt < 2; ++attempt) {
    // Row sources: assigned factors, children's messages, D-iSAM2's damping
    // rows (d_isam2_step.cpp), and
    // (second attempt) regularization rows; each row with a lower bound of
    // its first nonzero column, for the staircase QR.
    int rows = 0;
    for (FactorId f : q.factors) rows += static_cast<int>(factors_[f].linear.rows());
    for (CliqueId ch : q.children) rows += static_cast<int>(cliques_[ch].message.rows());
    rows += dampingRowCount(q, lambda);
    if (regularize) rows += fd;

    row_leading_.resize(rows);
    int r = 0;
    for (FactorId f : q.factors) {
      appendTriangularLeading(factors_[f].vars, static_cast<int>(factors_[f].linear.rows()), r);
    }
    for (CliqueId ch : q.children) {
      appendTriangularLeading(cliques_[ch].separator, static_cast<int>(cliques_[ch].message.rows()), r);
    }
    appendDampingLeading(q, lambda, r);
    if (regularize) {
      for (int i = 0; i < fd; ++i) row_leading_[r++] = i;
    }

    // Counting sort of rows by leading column (n: no nonzero on the left).
    std::vector<int>& count = rows_with_leading_le_;
    count.assign(n + 2, 0);
    for (int i = 0; i < rows; ++i) ++count[row_leading_[i] + 1];
    for (int k = 0; k <= n; ++k) count[k + 1] += count[k];  // count[k] = rows with leading < k
    std::vector<int>& dest = row_dest_;
    dest.resize(rows);
    {
      std::vector<int>& next = row_next_;
      next.assign(count.begin(), count.end() - 1);
      for (int i = 0; i < rows; ++i) dest[i] = next[row_leading_[i]]++;
    }

    if (work_.rows() < rows || work_.cols() < n + 1) {
      work_.resize(std::max<Eigen::Index>(work_.rows(), rows), std::max<Eigen::Index>(work_.cols(), n + 1));
    }
    auto W = work_.topLeftCorner(rows, n + 1);
    W.setZero();
    r = 0;
    for (FactorId f : q.factors) {
      scatterRows(factors_[f].linear, factors_[f].vars, W, n, dest.data() + r, 0);
      r += static_cast<int>(factors_[f].linear.rows());
    }
    for (CliqueId ch : q.children) {
      scatterRows(cliques_[ch].message, cliques_[ch].separator, W, n, dest.data() + r, 0);
      r += static_cast<int>(cliques_[ch].message.rows());
    }
    writeDampingRows(q, lambda, W, n, dest.data(), r);
    if (regularize) {
      const double s = std::sqrt(params_.regularization);
      for (int i = 0; i < fd; ++i, ++r) W(dest[r], i) = s;
    }

    // rows_with_leading_le[k] = rows with leading <= k = count[k + 1].
    // Frontal column norms, accumulated along the rows (W is row-major; each
    // column's sum still runs over the rows in order).
    column_norms_.setZero(fd);
    for (int i = 0; i < rows; ++i) column_norms_ += W.row(i).head(fd).transpose().cwiseAbs2();
    column_norms_ = column_norms_.cwiseSqrt();
    if (qr_workspace_.size() < rows + n + 1) qr_workspace_.resize(rows + n + 1);
    staircaseQrInPlace(W, n, count.data() + 1, qr_workspace_.data());

    bool deficient = rows < fd;
    for (int k = 0; k < fd && !deficient; ++k) {
      deficient = !(std::abs(W(k, k)) > params_.rank_tolerance * column_norms_[k]) || !std::isfinite(W(k, k));
    }
    if (deficient && !regularize) {
      regularize = true;
      ++stats.indeterminate_cliques;
      continue;
    }
    q.conditional = W.topRows(fd);
    const int message_rows = std::max(0, std::min(rows, n) - fd);
    q.message = W.block(fd, fd, message_rows, n - fd + 1);
    break;
  }
  q.replaced = true;
  if (params_.method == SmootherParams::Method::kDogleg) addCliqueGradient(c, 1.0);
}

}  // namespace rilo
