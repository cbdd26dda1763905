#pragma once
// An NLOS indicator for receivers that report the RX level but not the
// first-path power (other modules, other firmware, logs without the column):
// how far a range's RX level lies below the level a line-of-sight signal
// has at that distance, learnt from the ranges themselves.
//
// Why: without first-path power every range is judged by its residual alone,
// and with most anchors overhead and most ranges long, the NLOS excess that
// the mixture's LOS core takes at face value pushes the tag away from the
// ceiling (half a metre low on the independent office sims, docs/noise-
// models.md). A wall or a body that delays the first path also attenuates the
// signal: on those sims LOS ranges sit about 5 dB above a path-loss fit and
// NLOS ones 2 dB below it (spread ~3 dB), so the RX level alone separates
// most NLOS ranges from LOS ones.
//
// Rule. The last window_ranges ranges' (log10 range, RX level) are kept. The
// path-loss line RX = a + b log10(r) is fitted to all of them, then refitted
// (fit_iterations - 1 times) to the points at or above the previous line's
// median residual, so the NLOS majority of a harsh site does not drag it
// down. One refit: more let the slope wander (the exponent's spread over 200
// synthetic 70 %-NLOS sites: 0.04 for the plain fit, 0.13 after 4 refits),
// while the level at mid-range, what the deficit rests on, holds within
// 0.3 dB either way. The slope is the path-loss exponent's (b = -10 n, n clamped to
// [min_exponent, max_exponent]; free space, n = 2 clamped to those bounds,
// when the ranges span too little distance to fit it). RX levels outside
// [-150, 0] dBm are not signal levels and are ignored. One envelope serves the
// site: anchors with other transmit powers or antennas shift their own ranges'
// deficits (a per-anchor offset is not modelled). The LOS level is the median residual of the
// upper half. A range's deficit is that level minus its residual (dB, >= 0):
// it stands where the receiver's RX-minus-first-path gap stands, so the flag
// threshold (nlos_power_gap_db), the learnt threshold and the per-bin shifts
// (los_gap_calibration.h) apply to it, except that the learnt threshold may
// rise past the configured one for it (its scale is this envelope's, not
// the vendor's).
// Fixed storage; add() never allocates; the fit runs every refit_every ranges.
#include <array>
#include <cstdint>
#include <limits>

namespace rilo {

struct RxLevelEnvelopeParams {
  bool enabled = true;
  int window_ranges = 2048;    ///< ranges the fit uses (the newest), at most RxLevelEnvelope::kCapacity
  int min_ranges = 100;        ///< ranges before the first fit
  int refit_every = 64;        ///< ranges between two fits
  int fit_iterations = 2;      ///< fits: the first to all ranges, the others to the upper half
  double min_log10_span = 0.2; ///< log10(range) spread (10th to 90th percentile) needed to fit the exponent
  double min_exponent = 1.5;   ///< path-loss exponent bounds
  double max_exponent = 4.0;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

class RxLevelEnvelope {
 public:
  static constexpr int kCapacity = 4096;

  explicit RxLevelEnvelope(RxLevelEnvelopeParams params = {});

  /// One range (m) with its RX level (dBm); non-finite values, ranges <= 0 or
  /// beyond 10 km and RX levels outside [-150, 0] dBm are ignored.
  void add(double range_m, double rssi_dbm) noexcept;
  /// Whether a fit is in place.
  bool fitted() const noexcept { return fitted_; }
  /// How far rssi_dbm lies below the LOS level at range_m (dB, >= 0); NaN
  /// before the first fit or for non-finite input.
  double deficitDb(double range_m, double rssi_dbm) const noexcept;
  /// The fitted line's exponent n (RX = a - 10 n log10 r) and the LOS level
  /// at range_m (dBm); NaN before the first fit. For reports and tests.
  double exponent() const noexcept { return fitted_ ? -slope_ / 10.0 : std::numeric_limits<double>::quiet_NaN(); }
  double losLevelDbm(double range_m) const noexcept;
  void reset() noexcept;

 private:
  void refit() noexcept;
  static double log10Range(double range_m) noexcept;

  RxLevelEnvelopeParams params_;
  std::array<double, kCapacity> x_{}, y_{};  ///< log10 range, RX level (dBm)
  std::array<double, kCapacity> scratch_{};
  std::array<std::uint8_t, kCapacity> keep_{};
  int next_ = 0, filled_ = 0, since_fit_ = 0;
  bool fitted_ = false;
  double intercept_ = 0.0, slope_ = 0.0, los_level_ = 0.0;
};

}  // namespace rilo
