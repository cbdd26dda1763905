#pragma once
// Online per-link noise level from recent residuals: the IMU-Ultrasonic-UWB paper's "dynamic
// covariance estimation mechanism, which automatically adjusts measurement
// weights based on real-time channel conditions" (abstract, Sec. VI) and its
// "adaptive TDoA covariance scaling" (contributions). The paper gives no
// formula for it; this is our design.
//
// One entry per key: a UWB anchor for ranges, an ultrasonic beacon, an anchor
// pair for TDoA ((a, b) and (b, a) share one entry: a swapped pair flips the
// residual's sign, not its spread). The caller feeds residuals e (m) of that
// key, measured minus predicted: post-fit residuals of the smoother, or
// filter innovations together with their predicted-state variance P =
// H P_x H^T (m^2; 0 for post-fit residuals, whose leverage is small when a
// window has many more measurements than states).
//
// Estimator (Huber's "Proposal 2" scale, recursive, as a stochastic
// approximation), for each key:
//   warm-up  first n0 = min_samples residuals only buffered; sigma() reports
//            the nominal sigma. At n0: s^2 = (1.4826 median|e|)^2 - mean(P)
//            (MAD about zero: robust to up to half the warm-up being NLOS).
//   update   z^2     = e^2 / (s^2 + P)                      (standardized)
//            psi^2   = min(z^2, c^2) / beta(c),  beta(c) = E[min(Z^2, c^2)], Z ~ N(0, 1)
//            s^2    <- (1 - lambda) s^2 + lambda ((s^2 + P) psi^2 - P)
//            lambda  = max(1 / n, 1 / window_samples)       (n: samples so far)
//            s^2 clamped to [sigma_min^2, sigma_max^2] after every step.
// Why:
//  - Second moment about ZERO, not the variance: a persistently biased link
//    (an anchor behind a wall) is less trustworthy, its sigma should grow.
//  - beta(c) makes E[psi^2] = 1 for Gaussian residuals of sigma s: the fixed
//    point is the true sigma (unbiased for LOS noise).
//  - Clipping at c s bounds one sample's influence: a residual of any size
//    raises s^2 by at most the factor 1 + lambda (c^2 / beta - 1) (c = 2,
//    lambda = 0.01: 3.4 %, so a burst of 5 outliers of 5 m moves sigma by
//    < 9 %), while a persistent change moves it geometrically: a doubled noise
//    is tracked within ~1.2 window_samples, a return to the old level within
//    ~2 window_samples (variance x 1/4, 1 - 0.73 lambda per sample).
//  - Exponential forgetting with 1/n at the start: O(1) per sample, no
//    buffer per key after warm-up, and the warm-up estimate counts as n0
//    samples, not as the nominal.
//  - The bounds keep one link from taking over (sigma_min) or from being
//    silently dropped (sigma_max: the robust loss still sees it).
// Storage: a fixed-capacity open-addressing table of max_keys entries and
// their warm-up buffers, all allocated in the constructor; update() and the
// queries never allocate. A key beyond capacity is not tracked: update()
// returns kTableFull (counted in dropped()), and sigma() reports its nominal.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rilo {

enum class NoiseKind : std::uint8_t {
  kRange = 0,       ///< UWB range (TWR), key: anchor id
  kTdoa = 1,        ///< UWB TDoA, key: unordered anchor pair
  kUltrasonic = 2,  ///< ultrasonic range, key: beacon id
};

struct NoiseKey {
  NoiseKind kind = NoiseKind::kRange;
  std::uint32_t a = 0;  ///< anchor / beacon id; the smaller id of a TDoA pair
  std::uint32_t b = 0;  ///< the larger id of a TDoA pair; 0 otherwise

  static NoiseKey range(std::uint32_t anchor_id) { return {NoiseKind::kRange, anchor_id, 0}; }
  static NoiseKey ultrasonic(std::uint32_t beacon_id) { return {NoiseKind::kUltrasonic, beacon_id, 0}; }
  /// Pair of a TDoA row (order does not matter).
  static NoiseKey tdoa(std::uint32_t anchor_a, std::uint32_t anchor_b) {
    return anchor_a < anchor_b ? NoiseKey{NoiseKind::kTdoa, anchor_a, anchor_b}
                               : NoiseKey{NoiseKind::kTdoa, anchor_b, anchor_a};
  }
  bool operator==(const NoiseKey&) const = default;
};

/// Nominal level and bounds of one measurement kind (m).
struct NoiseKindParams {
  double nominal_sigma_m;  ///< reported until min_samples residuals of a key arrived
  double sigma_min_m;      ///< lower bound, > 0
  double sigma_max_m;      ///< upper bound, >= nominal >= min
};

struct DynamicCovarianceParams {
  NoiseKindParams range{0.15, 0.05, 2.0};       ///< UWB TWR (Ranging-IMU Fusion paper: 0.1-0.2 m LOS)
  NoiseKindParams tdoa{0.15, 0.05, 2.0};        ///< UWB TDoA difference
  NoiseKindParams ultrasonic{0.02, 0.005, 0.5}; ///< ultrasonic (cm-level in LOS)
  int max_keys = 64;                ///< table capacity (keys of all kinds together)
  double window_samples = 100.0;    ///< forgetting: lambda = 1 / window_samples per sample of a key, >= 2
  int min_samples = 20;             ///< residuals of a key before it departs from nominal, in [3, kMaxWarmupSamples]
  double huber_c = 2.0;             ///< clipping of the standardized residual (sigmas), > 0

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// Whether an estimator uses DynamicCovariance, and its settings (the graph
/// stream's RangeImuStreamOptions and the EKF's EkfParams carry one).
struct DynamicCovarianceOptions {
  bool enabled = false;  ///< off: every measurement gets its kind's configured sigma
  /// Table size, forgetting, warm-up, clipping and the per-kind bounds. The
  /// estimators replace the per-kind nominal_sigma_m by their configured
  /// sigmas (widening the bounds to include them when needed).
  DynamicCovarianceParams params;
  std::size_t max_pending = 128;  ///< graph stream: measurements of one state awaiting their post-fit residual, >= 1
  /// Kinds whose sigmas are estimated (the others keep their configured
  /// sigma). Two-way ranges are off: their asymmetric loss already models the
  /// NLOS tail, and a second moment inflated by it widens the loss's Gaussian
  /// core (worse RMSE on the office and hall sims; measured:
  /// docs/noise-models.md, Figures behind the defaults).
  bool range = false;
  bool tdoa = true;
  /// Ultrasonic beacons: off for the same reason (their loss is the
  /// asymmetric one too); measured: docs/noise-models.md, "TDoA rows the
  /// receiver flags (session 15)".
  bool ultrasonic = false;
};

enum class CovarianceUpdate {
  kWarmingUp,          ///< buffered; the key still reports its nominal sigma
  kUpdated,            ///< the key's sigma was updated
  kTableFull,          ///< a new key and no free entry: not tracked (dropped() counts these)
  kRejectedNonFinite,  ///< non-finite residual or negative / non-finite P: ignored
};

class DynamicCovariance {
 public:
  static constexpr int kMaxWarmupSamples = 64;

  /// Allocates the whole table. Throws std::invalid_argument (params.validate()).
  explicit DynamicCovariance(const DynamicCovarianceParams& params);

  /// One residual e = measured - predicted (m) of `key`; predicted_var_m2: the
  /// prediction's variance for innovations (m^2, 0 for post-fit residuals).
  CovarianceUpdate update(const NoiseKey& key, double residual_m, double predicted_var_m2 = 0.0);

  /// Current sigma of key (m), in [sigma_min, sigma_max] of its kind; the
  /// nominal while warming up or when the key is not tracked.
  double sigma(const NoiseKey& key) const;
  double variance(const NoiseKey& key) const { const double s = sigma(key); return s * s; }
  /// sigma / nominal sigma: the factor by which to scale a factor's sigma.
  double scale(const NoiseKey& key) const { return sigma(key) / kindParams(key.kind).nominal_sigma_m; }
  /// Residuals fed for key (0 when not tracked).
  std::int64_t samples(const NoiseKey& key) const;
  bool tracked(const NoiseKey& key) const { return find(key) >= 0; }
  /// Whether key left its warm-up (sigma() is estimated, not nominal).
  bool estimated(const NoiseKey& key) const;

  int size() const { return static_cast<int>(used_); }
  int capacity() const { return params_.max_keys; }
  std::uint64_t dropped() const { return dropped_; }  ///< updates refused for a full table
  const DynamicCovarianceParams& params() const { return params_; }
  const NoiseKindParams& kindParams(NoiseKind kind) const;
  /// beta(c) = E[min(Z^2, c^2)], Z ~ N(0, 1).
  static double consistency(double c);

  /// Forget every key (keeps the allocation).
  void reset();

 private:
  struct Entry {
    NoiseKey key;
    std::int64_t n = 0;        ///< residuals so far
    double s2 = 0.0;           ///< current sigma^2 estimate (m^2), valid after warm-up
    double warm_p_sum = 0.0;   ///< sum of P over the warm-up (m^2)
  };

  int find(const NoiseKey& key) const;  ///< entry index or -1
  std::size_t slotOf(const NoiseKey& key) const;
  void finishWarmup(Entry& e, double* buffer) const;

  DynamicCovarianceParams params_;
  double lambda_min_;                ///< 1 / window_samples
  double c2_;                        ///< huber_c^2
  double inv_beta_;                  ///< 1 / consistency(huber_c)
  std::vector<Entry> entries_;       ///< max_keys, first used_ in use
  std::vector<double> warmup_;       ///< max_keys * min_samples residuals
  std::vector<std::int32_t> slots_;  ///< open addressing: entry index or -1; size a power of two >= 2 max_keys
  std::size_t used_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace rilo
