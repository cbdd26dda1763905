#include "estimation/solver/normal_equations.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo {

namespace {

// Block (i, j) of H_f^T H_f for an M-row factor with DI- and DJ-column
// Jacobian blocks (JacobianBlock stores columns contiguously, stride = rows):
// fixed sizes let the compiler keep the dot products in registers. Added to
// the CSC values column by column (the upper triangle of a diagonal block).
template <int M, int DI, int DJ>
void addBlockProduct(const JacobianBlock& Hi, const JacobianBlock& Hj, bool diagonal, double* values,
                     const int* col_ptr, int row_start) {
  const Eigen::Map<const Eigen::Matrix<double, M, DI>> A(Hi.data());
  const Eigen::Map<const Eigen::Matrix<double, M, DJ>> B(Hj.data());
  const Eigen::Matrix<double, DI, DJ> P = A.transpose().lazyProduct(B);
  for (int jj = 0; jj < DJ; ++jj) {
    double* dst = values + col_ptr[jj] + row_start;
    const int rows = diagonal ? jj + 1 : DI;
    for (int ii = 0; ii < rows; ++ii) dst[ii] += P(ii, jj);
  }
}

/// The fixed-size kernel for the 15-row combined IMU factor, or false.
bool addImuBlockProduct(const JacobianBlock& Hi, const JacobianBlock& Hj, bool diagonal, double* values,
                        const int* col_ptr, int row_start) {
  if (Hi.rows() != 15) return false;
  const int di = static_cast<int>(Hi.cols()), dj = static_cast<int>(Hj.cols());
  if (di == 6 && dj == 6) {
    addBlockProduct<15, 6, 6>(Hi, Hj, diagonal, values, col_ptr, row_start);
  } else if (di == 6 && dj == 3) {
    addBlockProduct<15, 6, 3>(Hi, Hj, diagonal, values, col_ptr, row_start);
  } else if (di == 3 && dj == 6) {
    addBlockProduct<15, 3, 6>(Hi, Hj, diagonal, values, col_ptr, row_start);
  } else if (di == 3 && dj == 3) {
    addBlockProduct<15, 3, 3>(Hi, Hj, diagonal, values, col_ptr, row_start);
  } else {
    return false;
  }
  return true;
}

}  // namespace

std::size_t NormalEquations::position(Key k) const {
  auto it = position_.find(k);
  if (it == position_.end()) throw std::out_of_range("NormalEquations: key " + keyString(k) + " not in the ordering");
  return it->second;
}

void NormalEquations::setStructure(const FactorGraph& graph, const Values& values, std::span<const Key> ordering) {
  try {
    buildStructure(graph, values, ordering);
  } catch (...) {
    clear();  // never leave a half-built pattern behind
    throw;
  }
}

void NormalEquations::clear() {
  n_ = 0;
  ordering_.clear();
  position_.clear();
  offsets_.assign(1, 0);
  col_ptr_.assign(1, 0);
  row_idx_.clear();
  values_.clear();
  diag_idx_.clear();
  gradient_.resize(0);
  factor_key_begin_.assign(1, 0);
  factor_pos_.clear();
  factor_slot_begin_.assign(1, 0);
  slots_.clear();
}

void NormalEquations::buildStructure(const FactorGraph& graph, const Values& values, std::span<const Key> ordering) {
  const std::size_t nv = ordering.size();
  ordering_.assign(ordering.begin(), ordering.end());
  position_.clear();
  position_.reserve(nv);
  offsets_.assign(nv + 1, 0);
  for (std::size_t b = 0; b < nv; ++b) {
    const Key k = ordering_[b];
    if (!position_.emplace(k, b).second) {
      throw std::invalid_argument("NormalEquations: ordering repeats key " + keyString(k));
    }
    if (!values.exists(k)) throw std::invalid_argument("NormalEquations: key " + keyString(k) + " has no value");
    offsets_[b + 1] = offsets_[b] + values.dim(k);
  }
  n_ = offsets_[nv];

  // Factor key positions and the block adjacency (blocks a <= b per column b).
  std::vector<std::vector<std::size_t>> adjacency(nv);
  for (std::size_t b = 0; b < nv; ++b) adjacency[b].push_back(b);
  factor_key_begin_.assign(1, 0);
  factor_pos_.clear();
  for (std::size_t f = 0; f < graph.size(); ++f) {
    const auto& keys = graph[f]->keys();
    const std::size_t begin = factor_pos_.size();
    for (Key k : keys) {
      auto it = position_.find(k);
      if (it == position_.end()) {
        throw std::invalid_argument("NormalEquations: key " + keyString(k) + " of factor " + std::to_string(f) +
                                    " is not in the ordering");
      }
      for (std::size_t q = begin; q < factor_pos_.size(); ++q) {
        if (factor_pos_[q] == it->second) {
          throw std::invalid_argument("NormalEquations: factor " + std::to_string(f) + " repeats key " + keyString(k));
        }
      }
      factor_pos_.push_back(it->second);
    }
    factor_key_begin_.push_back(factor_pos_.size());
    for (std::size_t a = begin; a < factor_pos_.size(); ++a) {
      for (std::size_t c = begin; c < factor_pos_.size(); ++c) {
        if (factor_pos_[a] < factor_pos_[c]) adjacency[factor_pos_[c]].push_back(factor_pos_[a]);
      }
    }
  }
  // Row start of each block of column-block b (same for all of b's columns).
  std::vector<std::vector<int>> row_start(nv);
  for (std::size_t b = 0; b < nv; ++b) {
    auto& adj = adjacency[b];
    std::sort(adj.begin(), adj.end());
    adj.erase(std::unique(adj.begin(), adj.end()), adj.end());
    row_start[b].resize(adj.size());
    int acc = 0;
    for (std::size_t q = 0; q < adj.size(); ++q) {
      row_start[b][q] = acc;
      acc += varDim(adj[q]);
    }
  }

  // Scalar pattern: column jj of block b holds the full blocks a < b, then
  // rows offset(b)..offset(b)+jj of the diagonal block.
  col_ptr_.assign(static_cast<std::size_t>(n_) + 1, 0);
  std::size_t nnz = 0;
  for (std::size_t b = 0; b < nv; ++b) {
    const int above = row_start[b].back();  // the diagonal block is last in adjacency[b]
    for (int jj = 0; jj < varDim(b); ++jj) {
      nnz += static_cast<std::size_t>(above + jj + 1);
      if (nnz > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
        throw std::invalid_argument("NormalEquations: Hessian too large for 32-bit indices");
      }
      col_ptr_[static_cast<std::size_t>(offsets_[b] + jj) + 1] = static_cast<int>(nnz);
    }
  }
  row_idx_.resize(nnz);
  values_.assign(nnz, 0.0);
  diag_idx_.resize(static_cast<std::size_t>(n_));
  for (std::size_t b = 0; b < nv; ++b) {
    for (int jj = 0; jj < varDim(b); ++jj) {
      const int c = offsets_[b] + jj;
      int p = col_ptr_[static_cast<std::size_t>(c)];
      for (std::size_t a : adjacency[b]) {
        const int rows = a == b ? jj + 1 : varDim(a);
        for (int ii = 0; ii < rows; ++ii) row_idx_[static_cast<std::size_t>(p++)] = offsets_[a] + ii;
      }
      diag_idx_[static_cast<std::size_t>(c)] = p - 1;
    }
  }

  // Where each factor's blocks land.
  factor_slot_begin_.assign(1, 0);
  slots_.clear();
  for (std::size_t f = 0; f < graph.size(); ++f) {
    const std::size_t begin = factor_key_begin_[f];
    const std::size_t nk = factor_key_begin_[f + 1] - begin;
    for (std::size_t i = 0; i < nk; ++i) {
      for (std::size_t j = 0; j < nk; ++j) {
        const std::size_t pa = factor_pos_[begin + i];
        const std::size_t pb = factor_pos_[begin + j];
        if (pa > pb) continue;
        const auto& adj = adjacency[pb];
        const auto q = static_cast<std::size_t>(std::lower_bound(adj.begin(), adj.end(), pa) - adj.begin());
        slots_.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(j), row_start[pb][q]});
      }
    }
    factor_slot_begin_.push_back(slots_.size());
  }
  gradient_.setZero(n_);
}

void NormalEquations::linearize(const FactorGraph& graph, const Values& x) {
  const std::size_t n_factors = factor_key_begin_.size() - 1;
  if (graph.size() != n_factors) {
    throw std::invalid_argument("NormalEquations::linearize: graph has " + std::to_string(graph.size()) +
                                " factors, structure was built for " + std::to_string(n_factors));
  }
  std::fill(values_.begin(), values_.end(), 0.0);
  gradient_.setZero();
  for (std::size_t f = 0; f < n_factors; ++f) {
    const Factor& factor = *graph[f];
    factor.linearize(x, r_, H_);
    const Eigen::Index m = r_.size();
    const std::size_t kb = factor_key_begin_[f];
    const std::size_t nk = factor_key_begin_[f + 1] - kb;
    for (std::size_t k = 0; k < nk; ++k) {
      const std::size_t pos = factor_pos_[kb + k];
      if (H_[k].rows() != m || H_[k].cols() != varDim(pos)) {
        throw std::logic_error("NormalEquations: factor " + std::to_string(f) + " returned a " +
                               std::to_string(H_[k].rows()) + "x" + std::to_string(H_[k].cols()) + " block for key " +
                               keyString(ordering_[pos]));
      }
      gradient_.segment(offsets_[pos], varDim(pos)).noalias() += H_[k].transpose() * r_;
    }
    // Block (i, j) of H_f^T H_f, one column dot product per stored entry,
    // added in place: at these sizes (m <= 15 rows, 3 or 6 columns) a
    // matrix product goes through Eigen's GEMM packing, which cost more than
    // the arithmetic.
    for (std::size_t s = factor_slot_begin_[f]; s < factor_slot_begin_[f + 1]; ++s) {
      const BlockSlot& slot = slots_[s];
      const std::size_t pa = factor_pos_[kb + slot.i];
      const std::size_t pb = factor_pos_[kb + slot.j];
      const JacobianBlock& Hi = H_[slot.i];
      const JacobianBlock& Hj = H_[slot.j];
      const bool diagonal = slot.i == slot.j;
      const int col0 = offsets_[pb];
      if (addImuBlockProduct(Hi, Hj, diagonal, values_.data(), col_ptr_.data() + col0, slot.row_start)) continue;
      for (int jj = 0; jj < varDim(pb); ++jj) {
        double* dst = values_.data() + col_ptr_[static_cast<std::size_t>(col0 + jj)] + slot.row_start;
        const auto hj = Hj.col(jj);
        const int rows = diagonal ? jj + 1 : varDim(pa);
        for (int ii = 0; ii < rows; ++ii) dst[ii] += Hi.col(ii).dot(hj);
      }
    }
  }
}

void NormalEquations::multiplyHessian(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  y.setZero(n_);
  const int* row_idx = row_idx_.data();
  const double* values = values_.data();
  double* yp = y.data();
  const double* xp = x.data();
  for (int c = 0; c < n_; ++c) {
    // Column c holds rows above the diagonal, then the diagonal (last): the
    // upper part contributes H_rc x_c to y_r and H_rc x_r to y_c.
    const int begin = col_ptr_[static_cast<std::size_t>(c)];
    const int diag = diag_idx_[static_cast<std::size_t>(c)];
    const double xc = xp[c];
    double yc = 0.0;
    for (int p = begin; p < diag; ++p) {
      const int r = row_idx[p];
      yp[r] += values[p] * xc;
      yc += values[p] * xp[r];
    }
    yp[c] += values[diag] * xc + yc;
  }
}

}  // namespace rilo
