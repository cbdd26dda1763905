#pragma once
// RAII wrapper around CHOLMOD (SuiteSparse 5.x, 32-bit int indices): sparse
// Cholesky of symmetric positive definite matrices, Ceres style.
//
// - CholmodContext owns a cholmod_common (cholmod_start / cholmod_finish) and
//   the dense workspace reused by every solve. CHOLMOD never prints and never
//   exits: its error handler records status and message in the context.
// - CholmodFactor owns one cholmod_factor uniquely (move-only) and frees it
//   through the context that created it, which must outlive it.
// - Matrices are borrowed views (SymmetricCscView) of arrays the caller owns,
//   so a caller can fill values in place and refactorize without copying.
// - Failure is reported through CholmodResult (status + message), never by an
//   exception or abort. Only programming errors (null pointers, a factor of
//   another context, size mismatches) throw std::invalid_argument.
//
// - Threads: a context and its factors belong to one thread at a time;
//   contexts on different threads are independent.
//
// cholmod.h is not included here: users of the wrapper do not see SuiteSparse.
#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

struct cholmod_common_struct;
struct cholmod_factor_struct;
struct cholmod_dense_struct;

namespace rilo {

class SupernodalCholesky;

/// Upper triangle of a symmetric n x n matrix in compressed sparse column form:
/// column j holds rows row_idx[col_ptr[j] .. col_ptr[j+1]-1], all <= j and
/// ascending. Borrowed: the caller owns the arrays and keeps them alive during
/// the call. values may be null where only the pattern is needed (analyze).
struct SymmetricCscView {
  int n = 0;
  const int* col_ptr = nullptr;  ///< n + 1 entries, col_ptr[0] = 0
  const int* row_idx = nullptr;  ///< col_ptr[n] entries
  const double* values = nullptr;
};

enum class CholmodStatus {
  kOk,
  kNotPositiveDefinite,  ///< indefinite or numerically singular (see FactorizeOptions)
  kInvalidInput,         ///< CHOLMOD rejected the input (e.g. bad pattern)
  kOutOfMemory,
  kFailure,  ///< any other CHOLMOD error
};
const char* toString(CholmodStatus s);

/// Outcome of a wrapper call. message is empty on success.
struct CholmodResult {
  CholmodStatus status = CholmodStatus::kOk;
  std::string message;
  int failed_column = -1;  ///< kNotPositiveDefinite: first failing pivot (column of the permuted matrix)
  bool ok() const { return status == CholmodStatus::kOk; }
};

struct AnalyzeOptions {
  /// Let CHOLMOD follow the ordering with an elimination-tree postorder. It
  /// never changes fill but reorders columns (more and larger supernodes);
  /// keep it off when the given order itself matters (constrained orderings).
  bool postorder = false;
  /// Which code factorizes numerically (see factorize()).
  enum class Kernel {
    /// CHOLMOD: simplicial or supernodal as its flop heuristic picks, the
    /// supernodal one on the system BLAS.
    kCholmod,
    /// Always supernodal (CHOLMOD's symbolic analysis and solve), the numeric
    /// factorization by SupernodalCholesky on Eigen kernels: does not depend
    /// on the system BLAS (Debian's reference BLAS made CHOLMOD's supernodal
    /// path, and its simplicial one on the batch Hessians, 2-3x slower).
    kSupernodalEigen,
  };
  Kernel kernel = Kernel::kCholmod;
};

struct FactorizeOptions {
  /// Factorize A + shift * I (CHOLMOD's beta); 0 factorizes A.
  double shift = 0.0;
  /// Besides CHOLMOD's own test (a pivot <= 0), report kNotPositiveDefinite
  /// when a pivot is tiny relative to its diagonal entry: L_jj^2 < ratio * A_jj
  /// (LDL': D_jj < ratio * A_jj). The ratio is invariant to diagonal scaling;
  /// a numerically singular matrix (gauge freedom, unobserved direction) has
  /// ratios near machine epsilon, so 1e-12 separates it from a merely
  /// ill-conditioned one. 0 disables the test.
  double min_pivot_ratio = 0.0;
};

class CholmodContext;

/// A symbolic + numeric Cholesky factor. Unique owner of its cholmod_factor.
class CholmodFactor {
 public:
  CholmodFactor();
  ~CholmodFactor();
  CholmodFactor(CholmodFactor&& other) noexcept;
  CholmodFactor& operator=(CholmodFactor&& other) noexcept;
  CholmodFactor(const CholmodFactor&) = delete;
  CholmodFactor& operator=(const CholmodFactor&) = delete;

  bool empty() const { return L_ == nullptr; }
  /// Matrix dimension n (0 when empty).
  int size() const;
  /// True after a successful factorize(); solve() requires it.
  bool isNumeric() const { return numeric_ok_; }
  bool isSupernodal() const;
  /// Fill-reducing permutation used: pivot j eliminates row/column perm[j] of
  /// A. Returns a copy (the caller owns it); empty when the factor is empty.
  std::vector<int> permutation() const;
  /// Nonzeros of L predicted by the symbolic analysis.
  double factorNonzeros() const;
  /// Frees the factor (empty afterwards).
  void reset();

 private:
  friend class CholmodContext;
  CholmodFactor(CholmodContext* ctx, cholmod_factor_struct* L);

  CholmodContext* ctx_ = nullptr;
  cholmod_factor_struct* L_ = nullptr;
  bool numeric_ok_ = false;
  std::unique_ptr<SupernodalCholesky> eigen_;  // AnalyzeOptions::Kernel::kSupernodalEigen
};

class CholmodContext {
 public:
  /// cholmod_start with: no printing, errors recorded, one ordering method
  /// (the caller's), supernodal/simplicial chosen automatically. Throws
  /// std::runtime_error only if CHOLMOD cannot start.
  CholmodContext();
  /// Frees the workspace and calls cholmod_finish. Factors created by this
  /// context must be destroyed (or reset) before it.
  ~CholmodContext();
  // Factors keep a pointer to their context: not copyable, not movable.
  CholmodContext(const CholmodContext&) = delete;
  CholmodContext& operator=(const CholmodContext&) = delete;

  /// Symbolic analysis of A's pattern with the given elimination order
  /// (perm[j] = column of A eliminated j-th, a permutation of 0..n-1; empty =
  /// natural order). Ownership: on success *factor owns the new symbolic
  /// factor (any previous content is freed); on failure *factor is left empty.
  /// Reuse the factor for every factorize() of matrices with this pattern.
  CholmodResult analyze(const SymmetricCscView& A, std::span<const int> perm, const AnalyzeOptions& options,
                        CholmodFactor* factor);

  /// Numeric factorization of A (+ shift I) into factor, which must come from
  /// analyze() of this context on A's pattern. Not positive definite (CHOLMOD
  /// pivot <= 0, or the pivot-ratio test of options) returns
  /// kNotPositiveDefinite with failed_column set; the factor then stays
  /// unusable for solve() until a later factorize() succeeds. Allocation only
  /// the first time (numeric storage is kept in the factor). With
  /// Kernel::kSupernodalEigen, A must have the analyzed pattern (a different
  /// number of entries throws std::invalid_argument).
  CholmodResult factorize(const SymmetricCscView& A, const FactorizeOptions& options, CholmodFactor& factor);

  /// Solves A X = B for n_rhs right-hand sides. B and X are caller-owned
  /// column-major n x n_rhs arrays (may not overlap). Workspace is owned by
  /// the context and reused across calls of the same shape.
  CholmodResult solve(const CholmodFactor& factor, const double* B, int n_rhs, double* X);

  /// Last message reported by CHOLMOD's error handler ("" if none since the
  /// last wrapper call began).
  const std::string& lastMessage() const { return last_message_; }

 private:
  friend class CholmodFactor;
  friend class CholmodCallScope;
  void freeFactor(cholmod_factor_struct* L);
  /// CHOLMOD error handler: records into the context of the current call.
  static void onCholmodError(int status, const char* file, int line, const char* message);
  CholmodResult resultFromStatus(const char* what) const;

  cholmod_common_struct* common_ = nullptr;  // owned (new/delete + start/finish)
  cholmod_dense_struct* X_ = nullptr;        // solve2 workspace, owned
  cholmod_dense_struct* Y_ = nullptr;
  cholmod_dense_struct* E_ = nullptr;
  std::string last_message_;
  int last_status_ = 0;
};

}  // namespace rilo
