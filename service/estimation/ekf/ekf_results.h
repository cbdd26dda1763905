#pragma once
// What the error-state EKF's propagate() and updates return, and its counters.
#include <cstdint>

namespace rilo {

/// Outcome of ErrorStateEkf::propagate().
enum class PropagateStatus {
  kPropagated,       ///< state and covariance moved to the sample's time
  kFirstSample,      ///< sample at the filter's time: remembered as the interval start, nothing moved
  kNonPositiveDt,    ///< sample not after the filter's time (duplicate / out of order): ignored
  kGapTooLarge,      ///< interval > EkfParams::max_imu_dt_s: ignored, state and time unchanged
};

/// Outcome of one measurement update.
enum class UpdateStatus {
  kAccepted,    ///< state and covariance updated
  kGated,       ///< Mahalanobis distance above the chi-square gate: rejected, counted
  kZeroWeight,  ///< the robust loss gave (almost) zero weight: skipped, counted
};

struct EkfUpdateResult {
  UpdateStatus status = UpdateStatus::kAccepted;
  /// y = z - h(x_prior) of the range (first) row (m); > 0 <=> measured longer than predicted.
  double innovation = 0.0;
  /// innovation / sqrt(S_00), S the prior innovation covariance (unitless, signed).
  double normalized_innovation = 0.0;
  /// (H P H^T)_00: the prior state's share of S_00 (m^2), S_00 = this + sigma^2.
  double predicted_variance_m2 = 0.0;
  /// y^T S^-1 y over all rows (what the gate compares).
  double mahalanobis_sq = 0.0;
  /// Final IRLS weight of the range row (1 without a loss; measurement
  /// variance used = sigma^2 / weight). 1 when gated.
  double weight = 1.0;

  bool accepted() const { return status == UpdateStatus::kAccepted; }
};

/// Most rows one group update takes (ErrorStateEkf::updateTdoaGroup): fixed
/// capacity, no allocation. A TDoA group of 25 ms at 160 packets/s has 4.
inline constexpr int kEkfMaxGroupRows = 16;

/// Outcome of ErrorStateEkf::updateTdoaGroup(), per row in the caller's order.
struct EkfGroupResult {
  int rows = 0;
  int accepted = 0, gated = 0, zero_weight = 0;
  int recovered = 0;              ///< rows the gate refused that gate recovery applied all the same (counted in accepted too)
  int iterations = 0;             ///< iterations run (<= EkfParams::group_iterations)
  double mahalanobis_sq = 0.0;    ///< y^T S^-1 y of the rows that passed the gate (prior S, correlated R)
  /// Per row: status, innovation y = z - h(x_prior) (m), H P H^T (m^2), final weight.
  UpdateStatus status[kEkfMaxGroupRows] = {};
  double innovation[kEkfMaxGroupRows] = {};
  double predicted_variance_m2[kEkfMaxGroupRows] = {};
  double weight[kEkfMaxGroupRows] = {};
};

/// Per measurement kind.
struct EkfUpdateCounts {
  std::uint64_t accepted = 0;
  std::uint64_t gated = 0;
  std::uint64_t zero_weight = 0;
  std::uint64_t attempted() const { return accepted + gated + zero_weight; }
};

struct EkfCounters {
  std::uint64_t imu_propagated = 0;     ///< kPropagated
  std::uint64_t imu_non_positive_dt = 0;///< kNonPositiveDt
  std::uint64_t imu_gaps = 0;           ///< kGapTooLarge
  EkfUpdateCounts range;
  EkfUpdateCounts tdoa;
  EkfUpdateCounts ultrasonic;
  EkfUpdateCounts height_band;  ///< applyHeightBand updates
  EkfUpdateCounts vertical_speed;  ///< applyVerticalSpeedPrior updates
  EkfUpdateCounts zero_velocity;   ///< applyZeroVelocityPrior updates
  std::uint64_t tdoa_recovered = 0;  ///< TDoA rows the gate refused that gate recovery applied (also in tdoa.accepted)

  std::uint64_t updates() const { return range.accepted + tdoa.accepted + ultrasonic.accepted; }
  std::uint64_t gated() const { return range.gated + tdoa.gated + ultrasonic.gated; }
};

}  // namespace rilo
