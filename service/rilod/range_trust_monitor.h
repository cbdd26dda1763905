#pragma once
// Counts the ranges the tracking estimator did not trust, for the status
// topic's rejected_ranges (service_status.h):
//  - a range to an anchor id the estimator does not know (it drops those);
//  - a range whose robust weight, at the newest state right after the
//    smoother update that took it, is below 0.5: the range model's own loss
//    (makeRangeLoss with the graph's range_loss and range_noise) on the
//    whitened signed residual (measured - predicted) / sigma, predicted from
//    the state's pose moved on by its velocity to the range's time
//    (poseAtRangeTime), the lever arm and the surveyed anchor. That is the
//    IRLS weight the smoother gave the range at that estimate: the share of
//    the range it treated as NLOS/outlier. (rilo replay's NLOS figure judges
//    the same way at the final smoothed trajectory instead.)
// Only ranges that arrive while tracking are judged; a range whose state is
// not the newest one after an update (several states in one update, e.g. the
// hand-over) is dropped unjudged. The estimator thread owns it; no allocation
// per range after construction.
#include <cstdint>
#include <vector>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/noise/robust_loss.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

/// One judged range (published on rt/rilo/ranges).
struct RangeVerdict {
  std::uint32_t anchor_id = 0;
  double range_m = 0.0;
  double predicted_m = 0.0;  ///< from the state's pose moved on by its velocity to the range's time, the lever arm and the surveyed anchor
  double weight = 1.0;       ///< the range model's robust weight
  std::int64_t t_offset_ns = 0;  ///< the range's time minus its state's (0 to the state window)
};

class RangeTrustMonitor {
 public:
  static constexpr double kTrustedWeight = 0.5;  ///< below: the range counts as rejected

  /// `p_w_anchors[id]`: surveyed anchors (m, world); `graph`: the estimator's graph parameters.
  RangeTrustMonitor(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph);

  /// A range the tracking estimator was given. Unknown anchors count at once.
  void onRange(const RangeSample& range) noexcept;
  /// After an update whose newest state is `latest`: judges the pending
  /// ranges of that state's ranging group. Returns how many were rejected.
  std::uint64_t judge(const StateEstimate& latest) noexcept;
  /// The ranges the last judge() judged, in arrival order (no allocation: the
  /// storage is reserved at construction).
  const std::vector<RangeVerdict>& lastVerdicts() const noexcept { return verdicts_; }
  /// Tracking ended: forget the pending ranges.
  void reset() noexcept {
    pending_.clear();
    verdicts_.clear();
  }
  /// The tracker's state window (ns; Localizer::trackingStateWindowNs).
  void setStateWindow(std::int64_t same_state_window_ns) noexcept { group_window_ns_ = same_state_window_ns; }

  std::uint64_t rejected() const noexcept { return rejected_; }
  std::uint64_t judged() const noexcept { return judged_; }
  std::uint64_t unjudged() const noexcept { return unjudged_; }
  /// Robust weight of `range` at `pose` (exposed for the tests).
  double weight(const RangeSample& range, const Pose3& T_w_b) const noexcept;

 private:
  static constexpr std::size_t kMaxPending = 256;  // a full ranging group is a handful

  std::vector<Vec3> p_w_anchors_;
  RobustLossPtr loss_;
  double sigma_m_;
  Vec3 p_b_tag_;
  std::int64_t group_window_ns_;
  std::vector<RangeSample> pending_;
  std::vector<RangeVerdict> verdicts_;
  std::uint64_t rejected_ = 0, judged_ = 0, unjudged_ = 0;
};

}  // namespace rilo
