#pragma once
// Tracking-consistency check on two-way ranges: a range can be longer than
// the true distance (NLOS, multipath: the asymmetric model's tail) but not
// much shorter. Ranges much SHORTER than the tracked estimate predicts are
// therefore evidence that the estimate is wrong, not that the range is bad.
// The robust losses cannot see this (the short side of the asymmetric model
// is Gaussian: it pulls, slowly, through D-iSAM2's damping), and the other
// health checks neither: after a 9 m jump of the tag (a looped replay's
// seam) tracking stayed "healthy" at 1.6-3 m error for a whole 45 s pass.
//
// Rule. After each estimator update, the pending ranges of the newest
// state's group (and of earlier states at most `max_age_ns` older, which the
// same update absorbed) are judged at the newest pose: a range is short when
//     measured - predicted < -max(short_sigmas * sigma_m, short_floor_m)
// Over the last `window` judged ranges, a share of short ones above
// `max_short_share` (with at least `min_judged` judged) means the estimate
// is inconsistent with the ranging: the Localizer re-initializes.
//
// The same pass keeps the residuals of the last `kFlaggedWindow` ranges the
// receiver flagged as NLOS (power gap above flag_gap_db, range_model.h): a
// low quantile of them is the excess a flagged range typically carries at
// this site (FlaggedExcessParams; the Localizer hands it to the range model),
// and tells each judged range's residual to the NLOS memory (nlos_memory.h).
// Fixed storage: pending ranges and the window are allocated up front.
#include <array>
#include <cstdint>
#include <limits>
#include <vector>

#include "estimation/measurements/los_gap_calibration.h"
#include "estimation/measurements/nlos_memory.h"
#include "estimation/measurements/tag_lever_arms.h"
#include "math/pose3.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

struct RangeConsistencyParams {
  bool enabled = true;
  double short_sigmas = 5.0;     ///< threshold in LOS sigmas ...
  double short_floor_m = 0.75;   ///< ... but never below this (m): a walking tag moves between states
  int window = 40;               ///< judged ranges the share is taken over
  int min_judged = 20;           ///< fewer judged so far: no verdict
  double max_short_share = 0.3;  ///< above: inconsistent
  std::int64_t max_age_ns = 100'000'000;  ///< older pending ranges are dropped unjudged

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// The expected excess of ranges the receiver flags as NLOS, estimated on
/// line (range_model.h: taken off each flagged range before its loss, the
/// NLOS component or the mixture):
/// the `quantile` of the flagged ranges' residuals (measured - predicted) at
/// the tracked newest pose, over the last kFlaggedWindow, clamped to
/// [0, max_m]. A low quantile: the excess has a heavy tail, and the shift
/// must not over-correct (higher quantiles hurt most where there is no
/// excess). 0 turns it off. Measured, and a variant relative to the unflagged
/// ranges tried and dropped: docs/noise-models.md, Figures behind the defaults.
struct FlaggedExcessParams {
  double quantile = 0.25;
  int min_ranges = 50;  ///< fewer flagged ranges judged: no estimate (0 m)
  double max_m = 1.0;   ///< cap (m)

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

class RangeConsistencyMonitor {
 public:
  /// `p_w_anchors[id]` (m, world), the UWB antenna's lever arm (body, m), the
  /// LOS sigma of a range (m), the window in which ranges share a state (ns).
  /// flag_gap_db: the receiver's NLOS flag (RangeNoiseParams::nlos_power_gap_db; +inf: none).
  /// tag_arms: further antennas by tag id; a range is judged from the antenna that measured it.
  RangeConsistencyMonitor(std::vector<Vec3> p_w_anchors, const Vec3& p_b_tag, double sigma_m,
                          std::int64_t same_state_window_ns, RangeConsistencyParams params,
                          double flag_gap_db = std::numeric_limits<double>::infinity(), LosGapParams los_gap = {},
                          std::vector<TagLeverArm> tag_arms = {},
                          NlosMemory nlos_memory = NlosMemory(0, std::numeric_limits<double>::quiet_NaN(), {}));
  static constexpr int kFlaggedWindow = 200;

  /// A range given to the tracking estimator (unknown anchors are ignored).
  void onRange(const RangeSample& range) noexcept;
  /// After an update whose newest state is at `t_ns` with pose `T_w_b` and
  /// velocity `v_w`: judges the pending ranges it took, those of the state's
  /// own window where the velocity takes the tag by their time (as their
  /// factors predict them, RangeTimeOffset). Returns false when the window's
  /// share of short ranges is above the limit (see shortShare()).
  bool judge(std::int64_t t_ns, const Pose3& T_w_b, const Vec3& v_w = Vec3::Zero()) noexcept;
  /// Tracking (re)started: forget everything.
  void reset() noexcept;
  /// The tracker's state window (ns): ranges up to this after a state are its own.
  void setStateWindow(std::int64_t same_state_window_ns) noexcept { group_window_ns_ = same_state_window_ns; }

  /// Share of short ranges in the current window (0 if nothing judged).
  double shortShare() const noexcept;
  int judgedInWindow() const noexcept { return filled_; }
  /// measured - predicted (m) at `T_w_b`, for the tests.
  double residual(const RangeSample& range, const Pose3& T_w_b) const noexcept;
  /// Quantile q in [0, 1] of the residuals (m) of the last flagged ranges
  /// judged; NaN with fewer than min_count of them. Does not allocate.
  double flaggedQuantile(double q, int min_count) const noexcept;
  /// The NLOS flag threshold in use (dB): flag_gap_db, or lower once the
  /// judged ranges show where the LOS gaps end (los_gap_calibration.h).
  double flagGapDb() const noexcept { return los_gap_.threshold(); }
  const LosGapCalibrator& losGap() const noexcept { return los_gap_; }
  /// Every judged range's verdict by anchor (nlos_memory.h).
  const NlosMemory& nlosMemory() const noexcept { return nlos_memory_; }

 private:
  static constexpr std::size_t kMaxPending = 256;

  std::vector<Vec3> p_w_anchors_;
  Vec3 p_b_tag_;
  std::vector<TagLeverArm> tag_arms_;  ///< further antennas by tag id (RangeImuGraphParams::tag_lever_arms)
  double short_m_;
  std::int64_t group_window_ns_;
  RangeConsistencyParams params_;
  std::vector<RangeSample> pending_;
  std::vector<std::uint8_t> window_;  ///< ring of judged ranges: 1 short, 0 not
  int next_ = 0, filled_ = 0, short_in_window_ = 0;
  LosGapCalibrator los_gap_;
  std::array<double, kFlaggedWindow> flagged_{};          ///< ring of flagged ranges' residuals (m)
  mutable std::array<double, kFlaggedWindow> scratch_{};  ///< for nth_element
  int flagged_next_ = 0, flagged_filled_ = 0;
  NlosMemory nlos_memory_;
};

}  // namespace rilo
