#pragma once
// Which ranges the estimate treated as NLOS: a range whose robust weight at
// the final (smoothed) trajectory is below a threshold was down-weighted.
// Reported by `rilo replay` (summary.json: nlos) and, when the recording says
// which ranges were LOS (simulator, labelled data), scored against that
// truth: how many NLOS ranges were caught and how many LOS ranges were lost.
// The estimator never reads `los`; only this evaluation does.
#include <cstddef>
#include <optional>
#include <vector>

#include "estimation/measurements/range_model.h"
#include "estimation/measurements/tag_lever_arms.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "sensors/samples.h"

namespace rilo {

struct NlosClassification {
  std::size_t ranges = 0;        ///< ranges with a trajectory pose close enough in time
  std::size_t downweighted = 0;  ///< ... whose robust weight was below the threshold
  // Against the recording's los column (ranges with los 0 or 1 only).
  std::size_t labelled_nlos = 0, nlos_downweighted = 0;
  std::size_t labelled_los = 0, los_downweighted = 0;

  bool labelled() const { return labelled_nlos + labelled_los > 0; }
  double downweightedFraction() const { return ranges ? static_cast<double>(downweighted) / static_cast<double>(ranges) : 0.0; }
  /// Share of the truly NLOS ranges that were down-weighted (recall).
  double nlosCaught() const { return labelled_nlos ? static_cast<double>(nlos_downweighted) / static_cast<double>(labelled_nlos) : 0.0; }
  /// Share of the truly LOS ranges that were down-weighted (information lost).
  double losLost() const { return labelled_los ? static_cast<double>(los_downweighted) / static_cast<double>(labelled_los) : 0.0; }
};

struct NlosClassificationOptions {
  double weight_threshold = 0.5;     ///< below: down-weighted
  std::int64_t max_dt_ns = 50'000'000;  ///< ranges farther than this from every pose are skipped
  std::vector<TagLeverArm> tag_lever_arms;  ///< further antennas by tag id (p_b_tag for the others)
};

/// Classifies `ranges` (time order) against `trajectory` (time order; a range
/// is judged within max_dt_ns of its nearest pose, at the position
/// interpolated between the poses around it and the nearest's attitude:
/// a state holds the ranges of its same_state_window_s): the range as
/// `model` makes it a term at sigma_m (range_model.h), its residual (range -
/// |R p_b_tag + p - anchor|) / sigma weighted by the term's loss. A range the
/// receiver flagged as NLOS (the model's indicator) counts as down-weighted:
/// the estimator treated it as NLOS whatever its residual. Ranges to anchor
/// ids outside `p_w_anchors` are skipped.
NlosClassification classifyRanges(const std::vector<RangeSample>& ranges,
                                  const std::vector<RangeImuEstimator::TimedPose>& trajectory,
                                  const std::vector<Vec3>& p_w_anchors, const Vec3& p_b_tag, const RangeModel& model,
                                  double sigma_m, const NlosClassificationOptions& options = {});

}  // namespace rilo
