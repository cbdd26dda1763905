#pragma once
// The smoother interface used by the pipeline and the tools: feed new factors
// and the initial values of new variables, read the estimate.
//
// Implementations: BayesTreeSmoother (iSAM2, D-iSAM2, incremental dog-leg,
// optional fixed lag). Not thread-safe: one smoother per estimation thread.
#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>

#include "estimation/graph/factor.h"
#include "estimation/graph/values.h"

namespace rilo {

/// Timestamp (ns) of every new state variable; variables without one (anchors)
/// are never marginalized by a fixed-lag smoother.
using KeyTimestamps = std::unordered_map<Key, std::int64_t>;

/// What one update did; the figures behind the service's diagnostics.
struct UpdateStats {
  // Bayes tree
  int variables_added = 0;
  int factors_added = 0;
  int variables_relinearized = 0;
  int factors_linearized = 0;         ///< new + relinearized factors
  int variables_reeliminated = 0;     ///< frontal variables of the re-eliminated top
  int cliques_reeliminated = 0;       ///< cliques of the new top (first elimination)
  int cliques_back_substituted = 0;   ///< cliques re-solved by partial back-substitution (all tries)
  int indeterminate_cliques = 0;      ///< cliques that needed regularization (rank deficient)
  int cliques_total = 0;              ///< after the update
  int variables_total = 0;            ///< after the update
  int factors_total = 0;              ///< after the update (nonlinear + linear marginals)
  // Fixed lag
  int variables_marginalized = 0;
  int marginal_factors_created = 0;
  int marginal_factors_merged = 0;    ///< earlier marginals folded into a new one on the same clique
  int variables_reordered_for_marginalization = 0;  ///< extra keys re-eliminated so marginal keys become leaves
  // Step control
  int step_tries = 0;                 ///< D-iSAM2 lambda tries / dog-leg radius tries (1 = first try accepted)
  bool step_accepted = true;          ///< false: every try increased the error; the previous estimate was kept
  double lambda = 0.0;                ///< D-iSAM2: damping of the accepted try
  int damping_widened = 0;            ///< D-iSAM2: 1 when the damping had to cover the whole re-eliminated top
  double trust_radius = 0.0;          ///< dog-leg: radius after the update
  double error_before = 0.0;          ///< nonlinear error at the previous estimate with the new factors
  double error_after = 0.0;           ///< nonlinear error at the new estimate
  double time_s = 0.0;                ///< wall time of update() (steady clock)
};

class Smoother {
 public:
  virtual ~Smoother() = default;

  /// Adds factors and the initial values of new variables, then updates the
  /// estimate. Throws std::invalid_argument for inconsistent input (a value
  /// for an existing key, a factor key without a value, a factor on a
  /// marginalized variable), with nothing changed. Numerical trouble never
  /// throws: it is reported in UpdateStats.
  virtual UpdateStats update(const FactorGraph& new_factors, const Values& new_values,
                             const KeyTimestamps& timestamps = {}) = 0;

  /// Current estimate of every variable that has not been marginalized.
  virtual Values estimate() const = 0;
  /// Current estimate of one variable; throws std::out_of_range if unknown.
  virtual Variable estimate(Key key) const = 0;
  virtual bool exists(Key key) const = 0;

  /// Marginal covariance of one variable at the current linearization;
  /// nullopt (reason in *failure when given) if it cannot be computed.
  virtual std::optional<CovarianceBlock> marginalCovariance(Key key, std::string* failure = nullptr) = 0;

  /// Nonlinear error of all current factors (marginals included) at the estimate.
  virtual double error() const = 0;
  /// Moves the final estimates of the variables marginalized since the last
  /// call into `out` (appended, in marginalization order): the smoothed
  /// trajectory of a fixed-lag smoother. Nothing for smoothers without lag.
  virtual void drainMarginalized(std::vector<std::pair<Key, Variable>>& out) { (void)out; }
};

}  // namespace rilo
