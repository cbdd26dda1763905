#pragma once
// Numeric supernodal Cholesky (left-looking) on a supernodal symbolic
// structure computed elsewhere (CHOLMOD's analysis), with Eigen kernels.
//
// Why: CHOLMOD's supernodal numeric factorization spends its time in the BLAS
// (dgemm, dsyrk, dtrsm, dpotrf) on small dense blocks; with the reference BLAS
// Debian installs by default that ran at ~1.5 GFlop/s on the range + IMU
// Hessians (supernodes of one 15-variable state, ~45 rows). The same
// algorithm on Eigen's kernels does not depend on which BLAS the system has.
//
// Layout (CHOLMOD's supernodal L, lower triangular, in the permuted order):
// supernode s holds columns super[s] .. super[s+1]-1; its row indices are
// rows[pi[s] .. pi[s+1]) (ascending, the first nscol of them are its own
// columns), its values a column-major nsrow x nscol block at Lx + px[s]. The
// strictly upper part of each diagonal block is left zero.
#include <Eigen/Core>
#include <span>
#include <vector>

namespace rilo {

/// Supernodal structure (borrowed arrays, 32-bit indices).
struct SupernodalStructure {
  int n = 0;
  int nsuper = 0;
  const int* super = nullptr;  ///< nsuper + 1 entries
  const int* pi = nullptr;     ///< nsuper + 1 entries, into rows
  const int* px = nullptr;     ///< nsuper + 1 entries, into Lx
  const int* rows = nullptr;   ///< pi[nsuper] entries
  std::size_t x_size = 0;      ///< entries of Lx
};

class SupernodalCholesky {
 public:
  /// Prepares the assembly of matrices with the pattern (col_ptr, row_idx)
  /// (upper triangle, CSC, n x n, unpermuted) into `structure` under the
  /// permutation perm (perm[k] = row/column of A eliminated k-th; empty =
  /// identity). Returns false if an entry of A does not fit the structure.
  bool prepare(const SupernodalStructure& structure, std::span<const int> perm, const int* col_ptr,
               const int* row_idx);
  bool prepared() const { return prepared_; }
  /// Entries of A's pattern.
  std::size_t entries() const { return assembly_.size(); }

  /// Factorizes A + shift I (values in the pattern given to prepare()) into
  /// Lx (structure.x_size entries). Returns -1 on success, else the first
  /// column (permuted order) whose pivot was not positive; Lx is then partial.
  int factorize(const double* values, double shift, double* Lx);

  /// Solves A X = B with the factor in Lx (after a successful factorize()):
  /// B and X are column-major n x n_rhs, may be the same array.
  void solve(const double* Lx, const double* B, int n_rhs, double* X);

 private:
  SupernodalStructure st_;
  bool prepared_ = false;
  std::vector<int> perm_;         // perm_[k] = row/column of A eliminated k-th
  std::vector<int> assembly_;     // per entry of A: index into Lx
  std::vector<int> diagonal_;     // per permuted column: index of L_kk in Lx
  std::vector<int> super_of_;     // per permuted column: its supernode
  // Left-looking schedule: head_[s] lists the supernodes that update s next;
  // next_ links them; row_pos_[d] is where d's remaining rows start.
  std::vector<int> head_, next_, row_pos_;
  std::vector<int> local_row_;    // row -> position within the current supernode
  Eigen::VectorXd update_;        // dense update block
  Eigen::MatrixXd y_, below_;     // solve workspace
};

}  // namespace rilo
