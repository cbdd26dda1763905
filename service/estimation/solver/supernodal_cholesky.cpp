#include "estimation/solver/supernodal_cholesky.h"

#include <algorithm>
#include <cmath>

namespace rilo {

namespace {
using Panel = Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
using ConstPanel = Eigen::Map<const Eigen::MatrixXd, 0, Eigen::OuterStride<>>;
}  // namespace

bool SupernodalCholesky::prepare(const SupernodalStructure& structure, std::span<const int> perm, const int* col_ptr,
                                 const int* row_idx) {
  prepared_ = false;
  st_ = structure;
  const int n = st_.n;
  if (!perm.empty() && perm.size() != static_cast<std::size_t>(n)) return false;
  perm_.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) perm_[static_cast<std::size_t>(k)] = perm.empty() ? k : perm[static_cast<std::size_t>(k)];
  std::vector<int> iperm(static_cast<std::size_t>(n), -1);
  for (int k = 0; k < n; ++k) {
    const int p = perm_[static_cast<std::size_t>(k)];
    if (p < 0 || p >= n || iperm[static_cast<std::size_t>(p)] != -1) return false;
    iperm[static_cast<std::size_t>(p)] = k;
  }

  super_of_.assign(static_cast<std::size_t>(n), -1);
  diagonal_.assign(static_cast<std::size_t>(n), -1);
  std::size_t max_update = 0;
  for (int s = 0; s < st_.nsuper; ++s) {
    const int k1 = st_.super[s], k2 = st_.super[s + 1];
    const int nsrow = st_.pi[s + 1] - st_.pi[s];
    for (int c = k1; c < k2; ++c) {
      super_of_[static_cast<std::size_t>(c)] = s;
      diagonal_[static_cast<std::size_t>(c)] = st_.px[s] + (c - k1) * nsrow + (c - k1);
    }
    max_update = std::max(max_update, static_cast<std::size_t>(nsrow) * static_cast<std::size_t>(nsrow));
  }
  if (std::find(super_of_.begin(), super_of_.end(), -1) != super_of_.end()) return false;

  // Entries of A bucketed by their column in the permuted lower triangle.
  const int nnz = col_ptr[n];
  std::vector<int> bucket_start(static_cast<std::size_t>(n) + 1, 0);
  std::vector<int> entry_row(static_cast<std::size_t>(nnz)), entry_col(static_cast<std::size_t>(nnz));
  for (int j = 0; j < n; ++j) {
    for (int p = col_ptr[j]; p < col_ptr[j + 1]; ++p) {
      const int a = iperm[static_cast<std::size_t>(row_idx[p])], b = iperm[static_cast<std::size_t>(j)];
      entry_row[static_cast<std::size_t>(p)] = std::max(a, b);
      entry_col[static_cast<std::size_t>(p)] = std::min(a, b);
      ++bucket_start[static_cast<std::size_t>(std::min(a, b)) + 1];
    }
  }
  for (std::size_t c = 0; c < static_cast<std::size_t>(n); ++c) bucket_start[c + 1] += bucket_start[c];
  std::vector<int> bucket(static_cast<std::size_t>(nnz));
  {
    std::vector<int> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (int p = 0; p < nnz; ++p) {
      int& slot = fill[static_cast<std::size_t>(entry_col[static_cast<std::size_t>(p)])];
      bucket[static_cast<std::size_t>(slot++)] = p;
    }
  }

  assembly_.assign(static_cast<std::size_t>(nnz), -1);
  local_row_.assign(static_cast<std::size_t>(n), -1);
  for (int s = 0; s < st_.nsuper; ++s) {
    const int k1 = st_.super[s], k2 = st_.super[s + 1];
    const int psi = st_.pi[s], nsrow = st_.pi[s + 1] - psi;
    for (int k = 0; k < nsrow; ++k) local_row_[static_cast<std::size_t>(st_.rows[psi + k])] = k;
    for (int c = k1; c < k2; ++c) {
      for (int q = bucket_start[static_cast<std::size_t>(c)]; q < bucket_start[static_cast<std::size_t>(c) + 1]; ++q) {
        const int p = bucket[static_cast<std::size_t>(q)];
        const int r = entry_row[static_cast<std::size_t>(p)];
        const int local = local_row_[static_cast<std::size_t>(r)];
        if (local < 0 || st_.rows[psi + local] != r) return false;  // not in the structure
        assembly_[static_cast<std::size_t>(p)] = st_.px[s] + (c - k1) * nsrow + local;
      }
    }
  }
  head_.assign(static_cast<std::size_t>(st_.nsuper), -1);
  next_.assign(static_cast<std::size_t>(st_.nsuper), -1);
  row_pos_.assign(static_cast<std::size_t>(st_.nsuper), 0);
  update_.resize(static_cast<Eigen::Index>(max_update));
  prepared_ = true;
  return true;
}

int SupernodalCholesky::factorize(const double* values, double shift, double* Lx) {
  std::fill(Lx, Lx + st_.x_size, 0.0);
  for (std::size_t p = 0; p < assembly_.size(); ++p) Lx[assembly_[p]] += values[p];
  if (shift != 0.0) {
    for (int d : diagonal_) Lx[d] += shift;
  }
  std::fill(head_.begin(), head_.end(), -1);

  for (int s = 0; s < st_.nsuper; ++s) {
    const int k1 = st_.super[s], k2 = st_.super[s + 1];
    const int nscol = k2 - k1;
    const int psi = st_.pi[s], nsrow = st_.pi[s + 1] - psi;
    Panel S(Lx + st_.px[s], nsrow, nscol, Eigen::OuterStride<>(nsrow));
    for (int k = 0; k < nsrow; ++k) local_row_[static_cast<std::size_t>(st_.rows[psi + k])] = k;

    // Updates from every earlier supernode d with rows in columns k1..k2-1:
    // S -= L_d(rows >= k1) * L_d(rows in [k1, k2))^T, lower part.
    for (int d = head_[static_cast<std::size_t>(s)]; d != -1;) {
      const int d_next = next_[static_cast<std::size_t>(d)];
      const int pdi = st_.pi[d], pdend = st_.pi[d + 1];
      const int ndrow = pdend - pdi, ndcol = st_.super[d + 1] - st_.super[d];
      const int pdi1 = row_pos_[static_cast<std::size_t>(d)];
      int pdi2 = pdi1;
      while (pdi2 < pdend && st_.rows[pdi2] < k2) ++pdi2;
      const int ndrow1 = pdi2 - pdi1, ndrow2 = pdend - pdi1;
      const ConstPanel Ld(Lx + st_.px[d], ndrow, ndcol, Eigen::OuterStride<>(ndrow));
      Eigen::Map<Eigen::MatrixXd> C(update_.data(), ndrow2, ndrow1);
      C.noalias() = Ld.middleRows(pdi1 - pdi, ndrow2) * Ld.middleRows(pdi1 - pdi, ndrow1).transpose();
      for (int j = 0; j < ndrow1; ++j) {
        const int col = st_.rows[pdi1 + j] - k1;
        for (int i = j; i < ndrow2; ++i) S(local_row_[static_cast<std::size_t>(st_.rows[pdi1 + i])], col) -= C(i, j);
      }
      row_pos_[static_cast<std::size_t>(d)] = pdi2;
      if (pdi2 < pdend) {
        const int ancestor = super_of_[static_cast<std::size_t>(st_.rows[pdi2])];
        next_[static_cast<std::size_t>(d)] = head_[static_cast<std::size_t>(ancestor)];
        head_[static_cast<std::size_t>(ancestor)] = d;
      }
      d = d_next;
    }

    // Dense left-looking Cholesky of the panel: the diagonal block and,
    // in the same sweep, the rows below it (potrf and trsm at once).
    for (int j = 0; j < nscol; ++j) {
      auto column = S.col(j).tail(nsrow - j);
      if (j > 0) column.noalias() -= S.block(j, 0, nsrow - j, j) * S.row(j).head(j).transpose();
      const double pivot = column(0);
      if (!(pivot > 0.0)) return k1 + j;
      const double l_jj = std::sqrt(pivot);
      column(0) = l_jj;
      column.tail(nsrow - j - 1) /= l_jj;
    }

    if (nsrow > nscol) {
      row_pos_[static_cast<std::size_t>(s)] = psi + nscol;
      const int ancestor = super_of_[static_cast<std::size_t>(st_.rows[psi + nscol])];
      next_[static_cast<std::size_t>(s)] = head_[static_cast<std::size_t>(ancestor)];
      head_[static_cast<std::size_t>(ancestor)] = s;
    }
  }
  return -1;
}

void SupernodalCholesky::solve(const double* Lx, const double* B, int n_rhs, double* X) {
  const int n = st_.n;
  y_.resize(n, n_rhs);
  int max_below = 0;
  for (int s = 0; s < st_.nsuper; ++s) {
    max_below = std::max(max_below, st_.pi[s + 1] - st_.pi[s] - (st_.super[s + 1] - st_.super[s]));
  }
  if (below_.rows() < max_below || below_.cols() != n_rhs) below_.resize(max_below, n_rhs);
  for (int c = 0; c < n_rhs; ++c) {
    const double* b = B + static_cast<std::ptrdiff_t>(c) * n;
    for (int k = 0; k < n; ++k) y_(k, c) = b[perm_[static_cast<std::size_t>(k)]];
  }
  // Forward: L y = P b, supernode by supernode.
  for (int s = 0; s < st_.nsuper; ++s) {
    const int k1 = st_.super[s], nscol = st_.super[s + 1] - k1;
    const int psi = st_.pi[s], nsrow = st_.pi[s + 1] - psi, nbelow = nsrow - nscol;
    const ConstPanel S(Lx + st_.px[s], nsrow, nscol, Eigen::OuterStride<>(nsrow));
    auto ys = y_.middleRows(k1, nscol);
    S.topRows(nscol).triangularView<Eigen::Lower>().solveInPlace(ys);
    if (nbelow > 0) {
      auto below = below_.topRows(nbelow);
      below.noalias() = S.bottomRows(nbelow) * ys;
      for (int i = 0; i < nbelow; ++i) y_.row(st_.rows[psi + nscol + i]) -= below.row(i);
    }
  }
  // Backward: L^T x = y, in reverse.
  for (int s = st_.nsuper - 1; s >= 0; --s) {
    const int k1 = st_.super[s], nscol = st_.super[s + 1] - k1;
    const int psi = st_.pi[s], nsrow = st_.pi[s + 1] - psi, nbelow = nsrow - nscol;
    const ConstPanel S(Lx + st_.px[s], nsrow, nscol, Eigen::OuterStride<>(nsrow));
    auto ys = y_.middleRows(k1, nscol);
    if (nbelow > 0) {
      auto below = below_.topRows(nbelow);
      for (int i = 0; i < nbelow; ++i) below.row(i) = y_.row(st_.rows[psi + nscol + i]);
      ys.noalias() -= S.bottomRows(nbelow).transpose() * below;
    }
    S.topRows(nscol).triangularView<Eigen::Lower>().transpose().solveInPlace(ys);
  }
  for (int c = 0; c < n_rhs; ++c) {
    double* x = X + static_cast<std::ptrdiff_t>(c) * n;
    for (int k = 0; k < n; ++k) x[perm_[static_cast<std::size_t>(k)]] = y_(k, c);
  }
}

}  // namespace rilo
