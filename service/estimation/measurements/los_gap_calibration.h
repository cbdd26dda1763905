#pragma once
// Learns, from the ranges themselves, where the receiver's NLOS indicator
// (RX level minus first-path power, range_model.h) stops meaning LOS at this
// site and on this hardware, and moves the flag threshold there: lower than
// the configured one for the receiver's own gap, and for a gap that stands in
// from the RX level also higher (below).
//
// Why: the vendor's 6 dB (Decawave APS006) is a rule of thumb. Paths through
// one light wall keep a gap of 4-6 dB and a small excess (0.1-0.3 m) that the
// mixture's LOS core takes at face value; with anchors overhead that common
// excess pulls the tag down (the z error is the largest part of the office
// sims' error: 0.23-0.36 m of 0.24-0.53 m mean). Where the LOS gaps of a
// given receiver sit is a property of its antenna and front end, so it is
// measured rather than fixed.
//
// Rule. Ranges judged at the tracked newest pose (range_consistency.h) are
// binned by gap (bin_db wide, up to the threshold's bound, below); each bin
// keeps the residuals (measured - predicted) of its last kPerBin ranges. The
// reference is the median residual of the bins wholly below min_gap_db
// (pooled; at least reference_ranges of them): ranges there are LOS on any
// DW1000/DW3000 front end. A bin at or above min_gap_db with at least
// min_bin_ranges ranges whose median residual exceeds the reference by
// excess_sigmas LOS sigmas shows excess: most of its ranges carry one. Below
// the configured threshold, the threshold is the lower edge of the first
// such bin that the next filled bin confirms (the last bin searched stands
// alone; above the configured threshold, see the bound): residuals are taken at
// the tracked pose, whose error projects differently on the anchors that
// dominate each bin, and one bin's median crossed the step by that alone
// (own halls without the first-path column: the threshold sat at 3-4 dB,
// deep in their LOS ranges, a quarter of the time), while excess that
// really begins grows with the gap and shows in both. No such bin, or too
// little reference: the configured threshold. The comparison is against
// the reference rather than zero so that a pose bias common to all ranges
// cancels. Measured: docs/noise-models.md, "A flag threshold learnt from
// the ranges (session 22)", Figures behind the defaults, and "Where the
// RX-level flag ends (session 43)". excess_sigmas 0.5 is 4.5 standard
// errors of a full bin's median (2.2 at min_bin_ranges). Bins are (lo, hi],
// matching the flag gap > threshold.
// The same pass keeps, per bin from min_gap_db up to the configured
// threshold, the median excess over the reference (GapExcessTable): the
// shift a flagged range of that bin takes (range_model.h) in place of the
// site-wide flagged quantile (range_consistency.h), which the ranges above
// the vendor's threshold dominate. These bins carry small excesses that grow
// with the gap. Bins above the configured threshold keep the site-wide shift
// (a per-bin one was worse there: the component's heavy tail already carries
// the excess). Measured:
// docs/noise-models.md, "Per-bin shifts for the newly flagged ranges (session 23)".
//
// The bound. The configured threshold bounds the receiver's own gap. A gap
// that stands in from the RX level (Localizer::withRxLevelIndicator: the
// deficit below the learnt LOS envelope, read from min_gap_db up) is not on
// the vendor's scale: the envelope's LOS level is a median, and where LOS
// ranges are the majority (the own halls, 72-76 % LOS) it sits above their
// centre and a quarter of the LOS ranges lay more than the configured 3 dB
// of deficit below it, flagged and shifted by the component's mode. So
// while no receiver gap has come for kBins * kPerBin ranges (any receiver
// gap, binned or not: a mixed site keeps the vendor's bound for the
// receiver's flags, which share the one threshold), the threshold may rise
// up to rx_level_max_gap_db, but only through bins that showed they are LOS
// (filled, no excess): an unfilled bin or a bin with excess stops it there.
// The excess table stays below the configured threshold.
// Fed by RangeConsistencyMonitor::judge: off with range_consistency.enabled.
// Fixed storage; add() and threshold() never allocate.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

namespace rilo {

/// Per gap bin (lo, hi], bin_db wide from 0: the median residual of its
/// ranges above the LOS reference (m, >= 0; NaN where not known).
struct GapExcessTable {
  static constexpr int kBins = 32;
  double bin_db = 0.5;
  std::array<double, kBins> excess_m;

  GapExcessTable() { clear(); }
  void clear() noexcept { excess_m.fill(std::numeric_limits<double>::quiet_NaN()); }
  /// The bin (lo, hi] of a gap in (0, bins * bin_db] dB; the caller checks the range.
  static int binOf(double gap_db, double bin_db) noexcept {
    return static_cast<int>(std::ceil(gap_db / bin_db)) - 1;
  }
  /// The excess of a range with this gap (dB); NaN for a NaN gap, one outside the bins or a bin without one.
  double at(double gap_db) const noexcept {
    if (!(gap_db > 0.0 && gap_db <= kBins * bin_db)) return std::numeric_limits<double>::quiet_NaN();
    return excess_m[static_cast<std::size_t>(binOf(gap_db, bin_db))];
  }
};

struct LosGapParams {
  bool enabled = true;
  double bin_db = 0.5;             ///< gap bin width (dB)
  double min_gap_db = 3.0;         ///< never flag below this (dB); bins below it are the LOS reference
  int reference_ranges = 100;      ///< ranges needed below min_gap_db for a reference
  int min_bin_ranges = 30;         ///< a bin with fewer ranges gives no evidence
  double excess_sigmas = 0.5;      ///< median excess over the reference that marks a bin NLOS (LOS sigmas)
  int recompute_every = 40;        ///< ranges between two recomputations of the threshold
  /// Upper bound of the threshold while the gaps stand in from the RX level
  /// (dB on the same scale: min_gap_db + the deficit; 9 dB is a deficit of
  /// 6 dB, two spreads of the LOS RX level about its path-loss line, 2.5-3 dB
  /// on the own and the independent simulator's offices). Below the
  /// configured threshold it raises nothing; beyond the bins it is clamped.
  double rx_level_max_gap_db = 9.0;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

class LosGapCalibrator {
 public:
  static constexpr int kBins = GapExcessTable::kBins;
  static constexpr int kPerBin = 128;

  /// sigma_m: LOS range std-dev (m); max_gap_db: the configured threshold,
  /// the largest this returns for the receiver's own gaps (+inf: the
  /// indicator is off, nothing is learnt).
  LosGapCalibrator(LosGapParams params, double sigma_m, double max_gap_db);

  /// One judged range: its gap (dB; NaN or outside the bins: ignored),
  /// residual (m), and whether the gap stands in from the RX level.
  void add(double gap_db, double residual_m, bool from_rx_level = false) noexcept;
  /// The flag threshold in use (dB): the configured one until the data say
  /// otherwise (lower; higher only for RX-level gaps).
  double threshold() const noexcept { return threshold_db_; }
  /// The reference level (m; NaN until there is one), for reports and tests.
  double reference() const noexcept { return reference_m_; }
  /// The bins' excesses, from min_gap_db up to the configured threshold.
  const GapExcessTable& excessTable() const noexcept { return table_; }
  void reset() noexcept;

 private:
  void recompute() noexcept;
  /// Median of the first `n` values of scratch_ (reorders them).
  double scratchMedian(int n) const noexcept;

  /// The threshold's bound now: max_gap_db_, or rx_level_max_gap_db while
  /// no receiver gap came for kBins * kPerBin ranges.
  double boundDb() const noexcept;

  LosGapParams params_;

  double delta_m_;
  double max_gap_db_;
  int bins_used_ = 0;      ///< bins below the larger bound (at most kBins): RX-level gaps
  int receiver_bins_ = 0;  ///< bins below max_gap_db: the receiver's own gaps
  std::array<std::array<double, kPerBin>, kBins> residuals_{};
  /// RX-level gaps added (binned or not) since the last receiver gap (capped; kNoReceiverGap: none since construction or reset).
  static constexpr int kNoReceiverGap = kBins * kPerBin;
  int since_receiver_gap_ = kNoReceiverGap;
  std::array<int, kBins> next_{}, filled_{};
  mutable std::array<double, kBins * kPerBin> scratch_{};
  int since_recompute_ = 0;
  double threshold_db_;
  double reference_m_;
  GapExcessTable table_;
};

}  // namespace rilo
