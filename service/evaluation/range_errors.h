#pragma once
// How a recording's two-way ranges err against its ground truth: each range
// minus the true distance from its anchor to the antenna that measured it
// (the body pose interpolated at the range's time, the antenna's lever arm),
// and how the errors are distributed, per anchor and per the recording's LOS
// label where a simulator wrote one. The instrument for data we did not
// make: a new building's NLOS statistics, a bias per anchor, ranges stamped
// late (their error follows the radial speed: error = -tau * speed for a
// range measured tau before its stamp). Evaluation only: it reads ground
// truth and the los label, which the estimator never does.
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "hal/recording/recording.h"

namespace rilo {

struct RangeError {
  std::int64_t t_ns = 0;
  std::uint32_t anchor_id = 0;
  std::uint32_t tag_id = 0;
  double range_m = 0.0;   ///< measured
  double true_m = 0.0;    ///< |anchor - antenna| from the ground truth
  double error_m = 0.0;   ///< range_m - true_m
  /// d(true_m)/dt (m/s, positive moving away), by a central difference of the
  /// ground truth over +-RangeErrorOptions::radial_step_s; NaN where the
  /// ground truth does not reach.
  double radial_speed_m_s = std::numeric_limits<double>::quiet_NaN();
  int los = -1;  ///< the recording's label: 1 LOS, 0 NLOS, -1 none
};

struct RangeErrorOptions {
  double max_truth_gap_s = 0.1;  ///< no ground truth interpolated across a larger gap (s)
  double radial_step_s = 0.05;   ///< half-width of the radial speed's central difference (s)
  /// The true distance is taken this long before each range's stamp (s; 0:
  /// at the stamp). Tests whether ranges were measured before their stamp:
  /// the right shift takes the radial-speed slope to 0.
  double truth_shift_s = 0.0;
};

struct RangeErrors {
  std::vector<RangeError> errors;           ///< in the recording's order
  std::size_t without_truth = 0;            ///< ranges outside the ground truth or across a gap in it
  std::size_t unknown_anchor = 0;           ///< ranges to an anchor id not in anchors.csv
  std::size_t unknown_tag = 0;              ///< ranges from a tag id not in tags.csv
  std::size_t non_finite = 0;               ///< ranges whose value is not finite (a recording built in code)
};

/// The errors of every two-way range of `recording`. Throws
/// std::invalid_argument when the recording has no ground truth or the
/// options are out of range (naming the option).
RangeErrors rangeErrors(const Recording& recording, const RangeErrorOptions& options = {});

struct RangeErrorStats {
  std::size_t count = 0;
  double mean_m = std::numeric_limits<double>::quiet_NaN();
  double p1_m = std::numeric_limits<double>::quiet_NaN();
  double p5_m = std::numeric_limits<double>::quiet_NaN();
  double median_m = std::numeric_limits<double>::quiet_NaN();
  double p95_m = std::numeric_limits<double>::quiet_NaN();
  double p99_m = std::numeric_limits<double>::quiet_NaN();
  double short_share = std::numeric_limits<double>::quiet_NaN();  ///< error < -threshold: no NLOS path explains it
  double long_share = std::numeric_limits<double>::quiet_NaN();   ///< error > +threshold
  /// Least-squares slope of the error on the radial speed (s) and their
  /// correlation, over the errors with a radial speed (NaN for fewer than 3
  /// or no spread). A range measured tau seconds before its stamp: -tau, -1.
  double radial_slope_s = std::numeric_limits<double>::quiet_NaN();
  double radial_correlation = std::numeric_limits<double>::quiet_NaN();
};

/// Quantiles by linear interpolation between order statistics (the p-th of n
/// sorted values at index p (n - 1)).
RangeErrorStats summarizeRangeErrors(std::span<const RangeError> errors, double threshold_m = 0.3);

}  // namespace rilo
