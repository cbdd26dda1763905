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
// Fixed storage: pending ranges and the window are allocated up front.
#include <cstdint>
#include <vector>

#include "estimation/math/pose3.h"
#include "estimation/math/types.h"
#include "hal/samples.h"

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

class RangeConsistencyMonitor {
 public:
  /// `p_w_anchors[id]` (m, world), the UWB antenna's lever arm (body, m), the
  /// LOS sigma of a range (m), the window in which ranges share a state (ns).
  RangeConsistencyMonitor(std::vector<Vec3> p_w_anchors, const Vec3& p_b_tag, double sigma_m,
                          std::int64_t same_state_window_ns, RangeConsistencyParams params);

  /// A range given to the tracking estimator (unknown anchors are ignored).
  void onRange(const RangeSample& range) noexcept;
  /// After an update whose newest state is at `t_ns` with pose `T_w_b`:
  /// judges the pending ranges it took. Returns false when the window's share
  /// of short ranges is above the limit (see shortShare()).
  bool judge(std::int64_t t_ns, const Pose3& T_w_b) noexcept;
  /// Tracking (re)started: forget everything.
  void reset() noexcept;

  /// Share of short ranges in the current window (0 if nothing judged).
  double shortShare() const noexcept;
  int judgedInWindow() const noexcept { return filled_; }
  /// measured - predicted (m) at `T_w_b`, for the tests.
  double residual(const RangeSample& range, const Pose3& T_w_b) const noexcept;

 private:
  static constexpr std::size_t kMaxPending = 256;

  std::vector<Vec3> p_w_anchors_;
  Vec3 p_b_tag_;
  double short_m_;
  std::int64_t group_window_ns_;
  RangeConsistencyParams params_;
  std::vector<RangeSample> pending_;
  std::vector<std::uint8_t> window_;  ///< ring of judged ranges: 1 short, 0 not
  int next_ = 0, filled_ = 0, short_in_window_ = 0;
};

}  // namespace rilo
