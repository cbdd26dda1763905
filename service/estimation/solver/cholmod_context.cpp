#include "estimation/solver/cholmod_context.h"

#include <cholmod.h>

#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "estimation/solver/supernodal_cholesky.h"

namespace rilo {

namespace {

// Context of the CHOLMOD call running on this thread: the error handler has
// no user-data argument, so it finds its context here.
thread_local CholmodContext* t_current_context = nullptr;

void checkView(const SymmetricCscView& A, bool need_values, const char* where) {
  const char* problem = nullptr;
  if (A.n < 0) {
    problem = ": A.n is negative";
  } else if (A.col_ptr == nullptr) {
    problem = ": A.col_ptr is null";
  } else if (A.col_ptr[A.n] > 0 && A.row_idx == nullptr) {
    problem = ": A.row_idx is null";
  } else if (need_values && A.col_ptr[A.n] > 0 && A.values == nullptr) {
    problem = ": A.values is null";
  }
  if (problem) throw std::invalid_argument(std::string(where) + problem);
}

// A cholmod_sparse header over the caller's arrays (no copy). CHOLMOD's API
// takes non-const pointers but does not write to A in analyze/factorize.
cholmod_sparse sparseView(const SymmetricCscView& A) {
  cholmod_sparse a{};
  a.nrow = static_cast<std::size_t>(A.n);
  a.ncol = static_cast<std::size_t>(A.n);
  a.nzmax = static_cast<std::size_t>(A.col_ptr[A.n]);
  a.p = const_cast<int*>(A.col_ptr);
  a.i = const_cast<int*>(A.row_idx);
  a.nz = nullptr;
  a.x = const_cast<double*>(A.values);
  a.z = nullptr;
  a.stype = 1;  // symmetric, upper triangle stored
  a.itype = CHOLMOD_INT;
  a.xtype = A.values != nullptr ? CHOLMOD_REAL : CHOLMOD_PATTERN;
  a.dtype = CHOLMOD_DOUBLE;
  a.sorted = 1;
  a.packed = 1;
  return a;
}

// Diagonal entry of column c of an upper-triangle view (last entry when present).
double diagonalEntry(const SymmetricCscView& A, int c) {
  const int last = A.col_ptr[c + 1] - 1;
  if (last < A.col_ptr[c] || A.row_idx[last] != c) return 0.0;
  return A.values[last];
}

}  // namespace

/// Makes ctx the target of CHOLMOD's error handler for one wrapper call and
/// clears its last message.
class CholmodCallScope {
 public:
  explicit CholmodCallScope(CholmodContext* ctx) : previous_(t_current_context) {
    t_current_context = ctx;
    ctx->last_message_.clear();
    ctx->last_status_ = 0;
  }
  ~CholmodCallScope() { t_current_context = previous_; }
  CholmodCallScope(const CholmodCallScope&) = delete;
  CholmodCallScope& operator=(const CholmodCallScope&) = delete;

 private:
  CholmodContext* previous_;
};

const char* toString(CholmodStatus s) {
  switch (s) {
    case CholmodStatus::kOk:
      return "ok";
    case CholmodStatus::kNotPositiveDefinite:
      return "not positive definite";
    case CholmodStatus::kInvalidInput:
      return "invalid input";
    case CholmodStatus::kOutOfMemory:
      return "out of memory";
    case CholmodStatus::kFailure:
      return "failure";
  }
  return "unknown";
}

// ---------------------------------------------------------------- factor ---

CholmodFactor::CholmodFactor() = default;

CholmodFactor::CholmodFactor(CholmodContext* ctx, cholmod_factor_struct* L) : ctx_(ctx), L_(L) {}

CholmodFactor::~CholmodFactor() { reset(); }

CholmodFactor::CholmodFactor(CholmodFactor&& other) noexcept
    : ctx_(std::exchange(other.ctx_, nullptr)),
      L_(std::exchange(other.L_, nullptr)),
      numeric_ok_(std::exchange(other.numeric_ok_, false)),
      eigen_(std::move(other.eigen_)) {}

CholmodFactor& CholmodFactor::operator=(CholmodFactor&& other) noexcept {
  if (this != &other) {
    reset();
    ctx_ = std::exchange(other.ctx_, nullptr);
    L_ = std::exchange(other.L_, nullptr);
    numeric_ok_ = std::exchange(other.numeric_ok_, false);
    eigen_ = std::move(other.eigen_);
  }
  return *this;
}

void CholmodFactor::reset() {
  if (L_ != nullptr && ctx_ != nullptr) ctx_->freeFactor(L_);
  L_ = nullptr;
  numeric_ok_ = false;
  eigen_.reset();
}

int CholmodFactor::size() const { return L_ ? static_cast<int>(L_->n) : 0; }

bool CholmodFactor::isSupernodal() const { return L_ != nullptr && L_->is_super != 0; }

std::vector<int> CholmodFactor::permutation() const {
  if (!L_) return {};
  const int* perm = static_cast<const int*>(L_->Perm);
  return std::vector<int>(perm, perm + L_->n);
}

double CholmodFactor::factorNonzeros() const {
  if (!L_) return 0.0;
  const int* counts = static_cast<const int*>(L_->ColCount);
  double nnz = 0.0;
  for (std::size_t j = 0; j < L_->n; ++j) nnz += counts[j];
  return nnz;
}

// --------------------------------------------------------------- context ---

CholmodContext::CholmodContext() : common_(new cholmod_common) {
  if (!cholmod_start(common_)) {
    delete common_;
    throw std::runtime_error("CholmodContext: cholmod_start failed");
  }
  common_->print = 0;                                        // never write to stdout/stderr ...
  common_->error_handler = &CholmodContext::onCholmodError;  // ... record instead
  common_->quick_return_if_not_posdef = 1;
  common_->nmethods = 1;  // exactly the caller's ordering (set per analyze)
  common_->method[0].ordering = CHOLMOD_NATURAL;
  common_->postorder = 0;
  common_->supernodal = CHOLMOD_AUTO;
}

CholmodContext::~CholmodContext() {
  CholmodCallScope scope(this);
  cholmod_free_dense(&X_, common_);
  cholmod_free_dense(&Y_, common_);
  cholmod_free_dense(&E_, common_);
  cholmod_finish(common_);
  delete common_;
}

void CholmodContext::onCholmodError(int status, const char* file, int line, const char* message) {
  CholmodContext* ctx = t_current_context;
  if (ctx == nullptr) return;
  ctx->last_status_ = status;
  ctx->last_message_ =
      std::string(message ? message : "") + " (" + (file ? file : "?") + ":" + std::to_string(line) + ")";
}

void CholmodContext::freeFactor(cholmod_factor_struct* L) {
  CholmodCallScope scope(this);
  cholmod_free_factor(&L, common_);
}

CholmodResult CholmodContext::resultFromStatus(const char* what) const {
  CholmodResult r;
  switch (common_->status) {
    case CHOLMOD_OUT_OF_MEMORY:
      r.status = CholmodStatus::kOutOfMemory;
      break;
    case CHOLMOD_INVALID:
    case CHOLMOD_TOO_LARGE:
      r.status = CholmodStatus::kInvalidInput;
      break;
    case CHOLMOD_NOT_POSDEF:
      r.status = CholmodStatus::kNotPositiveDefinite;
      break;
    default:
      r.status = CholmodStatus::kFailure;
      break;
  }
  r.message = std::string(what) + ": " +
              (last_message_.empty() ? "CHOLMOD status " + std::to_string(common_->status) : last_message_);
  return r;
}

CholmodResult CholmodContext::analyze(const SymmetricCscView& A, std::span<const int> perm,
                                      const AnalyzeOptions& options, CholmodFactor* factor) {
  if (factor == nullptr) throw std::invalid_argument("CholmodContext::analyze: factor is null");
  checkView(A, false, "CholmodContext::analyze");
  if (!perm.empty()) {
    if (perm.size() != static_cast<std::size_t>(A.n)) {
      throw std::invalid_argument("CholmodContext::analyze: perm has " + std::to_string(perm.size()) +
                                  " entries, A.n is " + std::to_string(A.n));
    }
    std::vector<char> seen(perm.size(), 0);
    for (int p : perm) {
      if (p < 0 || p >= A.n || seen[static_cast<std::size_t>(p)]) {
        throw std::invalid_argument("CholmodContext::analyze: perm is not a permutation of 0..n-1");
      }
      seen[static_cast<std::size_t>(p)] = 1;
    }
  }
  factor->reset();
  CholmodCallScope scope(this);
  cholmod_sparse a = sparseView(A);
  common_->nmethods = 1;
  common_->method[0].ordering = perm.empty() ? CHOLMOD_NATURAL : CHOLMOD_GIVEN;
  common_->postorder = options.postorder ? 1 : 0;
  const bool eigen = options.kernel == AnalyzeOptions::Kernel::kSupernodalEigen;
  common_->supernodal = eigen ? CHOLMOD_SUPERNODAL : CHOLMOD_AUTO;
  cholmod_factor* L =
      cholmod_analyze_p(&a, perm.empty() ? nullptr : const_cast<int*>(perm.data()), nullptr, 0, common_);
  common_->supernodal = CHOLMOD_AUTO;
  if (L == nullptr) return resultFromStatus("cholmod_analyze_p");
  *factor = CholmodFactor(this, L);
  if (eigen) {
    // Numeric storage once (the symbolic factor has none); factorize() fills it.
    if (!L->is_super || !cholmod_change_factor(CHOLMOD_REAL, 1, 1, 1, 1, L, common_)) {
      CholmodResult r = resultFromStatus("cholmod_change_factor");
      factor->reset();
      return r;
    }
    SupernodalStructure st;
    st.n = static_cast<int>(L->n);
    st.nsuper = static_cast<int>(L->nsuper);
    st.super = static_cast<const int*>(L->super);
    st.pi = static_cast<const int*>(L->pi);
    st.px = static_cast<const int*>(L->px);
    st.rows = static_cast<const int*>(L->s);
    st.x_size = L->xsize;
    auto kernel = std::make_unique<SupernodalCholesky>();
    if (!kernel->prepare(st, std::span<const int>(static_cast<const int*>(L->Perm), L->n), A.col_ptr, A.row_idx)) {
      factor->reset();
      return {CholmodStatus::kInvalidInput, "CholmodContext::analyze: A does not fit its supernodal structure", -1};
    }
    factor->eigen_ = std::move(kernel);
  }
  return {};
}

CholmodResult CholmodContext::factorize(const SymmetricCscView& A, const FactorizeOptions& options,
                                        CholmodFactor& factor) {
  if (factor.empty() || factor.ctx_ != this) {
    throw std::invalid_argument("CholmodContext::factorize: factor is empty or from another context");
  }
  checkView(A, true, "CholmodContext::factorize");
  if (A.n != factor.size()) {
    throw std::invalid_argument("CholmodContext::factorize: A.n " + std::to_string(A.n) +
                                " differs from the analyzed size " + std::to_string(factor.size()));
  }
  factor.numeric_ok_ = false;
  CholmodCallScope scope(this);
  cholmod_factor* L = factor.L_;
  int ok = 0;
  if (factor.eigen_) {
    if (A.col_ptr[A.n] != static_cast<int>(factor.eigen_->entries())) {
      throw std::invalid_argument("CholmodContext::factorize: A's pattern differs from the analyzed one");
    }
    const int failed = factor.eigen_->factorize(A.values, options.shift, static_cast<double*>(L->x));
    L->minor = failed < 0 ? L->n : static_cast<std::size_t>(failed);
    common_->status = CHOLMOD_OK;  // not left over from an earlier CHOLMOD call
    ok = 1;
  } else {
    cholmod_sparse a = sparseView(A);
    double beta[2] = {options.shift, 0.0};
    ok = cholmod_factorize_p(&a, beta, nullptr, 0, L, common_);
  }
  if (common_->status == CHOLMOD_NOT_POSDEF || (ok && L->minor < L->n)) {
    CholmodResult r;
    r.status = CholmodStatus::kNotPositiveDefinite;
    r.failed_column = static_cast<int>(L->minor);
    r.message = "CHOLMOD: not positive definite at pivot " + std::to_string(L->minor);
    return r;
  }
  if (!ok || common_->status < CHOLMOD_OK) return resultFromStatus("cholmod_factorize_p");

  // Pivot test on every column (also catches the negative D that a simplicial
  // LDL' factorization accepts without complaint).
  const int n = A.n;
  const int* perm = static_cast<const int*>(L->Perm);
  const double* Lx = static_cast<const double*>(L->x);
  auto checkPivot = [&](int j, double pivot, CholmodResult& r) {
    const int c = perm ? perm[j] : j;
    const double a_cc = diagonalEntry(A, c) + options.shift;
    if (pivot > 0.0 && pivot >= options.min_pivot_ratio * a_cc) return true;
    r.status = CholmodStatus::kNotPositiveDefinite;
    r.failed_column = j;
    char buf[160];
    std::snprintf(buf, sizeof buf,
                  "numerically not positive definite: pivot %.3g at column %d (row/column %d of A, diagonal %.3g, "
                  "min ratio %.3g)",
                  pivot, j, c, a_cc, options.min_pivot_ratio);
    r.message = buf;
    return false;
  };
  CholmodResult r;
  if (L->is_super) {
    const int* super = static_cast<const int*>(L->super);
    const int* pi = static_cast<const int*>(L->pi);
    const int* px = static_cast<const int*>(L->px);
    for (std::size_t s = 0; s < L->nsuper; ++s) {
      const int nsrow = pi[s + 1] - pi[s];
      for (int j = super[s]; j < super[s + 1]; ++j) {
        const int jj = j - super[s];
        const double l_jj = Lx[px[s] + jj * nsrow + jj];
        if (!checkPivot(j, l_jj * l_jj, r)) return r;
      }
    }
  } else {
    const int* Lp = static_cast<const int*>(L->p);
    for (int j = 0; j < n; ++j) {
      const double d = Lx[Lp[j]];  // LL': L_jj; LDL': D_jj
      if (!checkPivot(j, L->is_ll ? d * d : d, r)) return r;
    }
  }
  factor.numeric_ok_ = true;
  return r;
}

CholmodResult CholmodContext::solve(const CholmodFactor& factor, const double* B, int n_rhs, double* X) {
  if (factor.empty() || factor.ctx_ != this) {
    throw std::invalid_argument("CholmodContext::solve: factor is empty or from another context");
  }
  if (B == nullptr || X == nullptr) throw std::invalid_argument("CholmodContext::solve: B or X is null");
  if (n_rhs < 1) throw std::invalid_argument("CholmodContext::solve: n_rhs must be >= 1");
  if (!factor.numeric_ok_) {
    return {CholmodStatus::kInvalidInput, "CholmodContext::solve: factor holds no successful factorization", -1};
  }
  const int n = factor.size();
  if (n == 0) return {};
  if (factor.eigen_) {
    factor.eigen_->solve(static_cast<const double*>(factor.L_->x), B, n_rhs, X);
    return {};
  }
  CholmodCallScope scope(this);
  cholmod_dense b{};
  b.nrow = static_cast<std::size_t>(n);
  b.ncol = static_cast<std::size_t>(n_rhs);
  b.nzmax = b.nrow * b.ncol;
  b.d = b.nrow;
  b.x = const_cast<double*>(B);
  b.z = nullptr;
  b.xtype = CHOLMOD_REAL;
  b.dtype = CHOLMOD_DOUBLE;
  if (!cholmod_solve2(CHOLMOD_A, factor.L_, &b, nullptr, &X_, nullptr, &Y_, &E_, common_)) {
    return resultFromStatus("cholmod_solve2");
  }
  const double* x = static_cast<const double*>(X_->x);
  for (int c = 0; c < n_rhs; ++c) {
    std::memcpy(X + static_cast<std::size_t>(c) * static_cast<std::size_t>(n), x + static_cast<std::size_t>(c) * X_->d,
                sizeof(double) * static_cast<std::size_t>(n));
  }
  return {};
}

}  // namespace rilo
