#pragma once
// Accuracy of an estimated trajectory against a recording's ground truth:
// association by time, absolute position error (APE) and relative pose error
// (RPE). Used by `rilo eval`, `rilo replay`'s summary and the tests, so they
// all measure the same thing.
//
// Association. Every estimated pose is paired with the ground-truth pose
// nearest in time (a tie goes to the later one) if |t_est - t_truth| <=
// max_dt_ns; there is no interpolation and several estimated poses may share
// one ground-truth pose. Poses without a partner are counted and listed, never
// dropped silently.
//
// APE (positions only, no alignment: the anchors fix the frame):
// e_k = p_est_k - p_truth_k over the associated pairs, as |e| (3D), |e_xy|
// (horizontal) and |e_z| (vertical); statistics from positionErrorStats.
//
// RPE (evo's convention "relative pose deltas", PoseRelation translation_part
// and rotation_angle_deg): for a pair (i, j) of associated poses with
//   D_truth = T_truth_i^-1 T_truth_j,   D_est = T_est_i^-1 T_est_j
//   E = D_truth^-1 D_est
//   translation error = |E.p| = |D_truth.p - D_est.p|   (m; the two are equal
//                       because E.p = R_truth_rel^T (D_est.p - D_truth.p))
//   rotation error    = angle of E.R = |Log(R_truth_rel^T R_est_rel)|   (deg, in [0, 180])
// The relative motion is expressed in the body frame at i, so a constant
// offset or a constant rotation of the whole trajectory gives 0.
// Pairs: like evo's --all_pairs, every associated pose i starts a pair; its
// partner j > i is the associated pose whose separation from i is closest to
// delta (of the last one below and the first one at or above delta; a tie
// goes to the later), accepted if |separation - delta| <= rel_tol * delta
// (evo's default rel_delta_tol = 0.1). Starts without an acceptable partner
// (near the end, across gaps in the estimate) give no pair. Separation:
//  - RpeDelta::kSeconds: t_est_j - t_est_i (estimate times);
//  - RpeDelta::kMeters: the ground truth's travelled distance (arc length of
//    the polyline through every ground-truth position, not only the
//    associated ones) between the partners of i and j. evo measures the path
//    along the associated reference poses instead; the two agree when the
//    ground truth is no denser than the estimate.
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "evaluation/trajectory_error.h"
#include "evaluation/tum.h"
#include "hal/recording/recording.h"

namespace rilo {

inline constexpr std::int64_t kDefaultAssociationMaxDtNs = 50'000'000;

struct PoseAssociation {
  /// (index into the estimate, index into the ground truth), in estimate order.
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  /// Estimate indices without ground truth within the tolerance.
  std::vector<std::size_t> unmatched;
  std::int64_t max_abs_dt_ns = 0;  ///< largest |t_est - t_truth| among the pairs
};

/// `truth` must be in strictly increasing time order (the recording reader
/// guarantees it); `estimate` may be in any order. Throws
/// std::invalid_argument if max_dt_ns < 0.
PoseAssociation associateByTime(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                std::int64_t max_dt_ns = kDefaultAssociationMaxDtNs);

/// APE of the associated pairs (see above).
PositionErrorStats absolutePositionError(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                         const PoseAssociation& association);

/// Estimated positions paired with the ground truth nearest in time (within
/// `max_dt_ns`; no alignment: the anchors fix the frame). Unmatched poses are
/// not in the statistics; associateByTime counts them.
PositionErrorStats positionErrorAgainst(const std::vector<RangeImuEstimator::TimedPose>& poses,
                                        const std::vector<GroundTruthPose>& truth,
                                        std::int64_t max_dt_ns = kDefaultAssociationMaxDtNs);

/// Pose age up to which the online estimate counts as tracking (trackedShare).
inline constexpr std::int64_t kDefaultTrackedMaxAgeNs = 1'000'000'000;

/// Share of [t0_ns, t1_ns] in which the newest pose at or before the time is
/// at most `max_age_ns` old: how much of a recording an online estimate
/// covered. APE is taken over the poses that exist, so a run that starts late
/// or drops out scores on its easy seconds alone; this says how many those
/// were. `poses` in non-decreasing time order. 0 for an empty interval.
/// Throws std::invalid_argument if max_age_ns < 0 or the poses are out of order.
double trackedShare(const std::vector<RangeImuEstimator::TimedPose>& poses, std::int64_t t0_ns, std::int64_t t1_ns,
                    std::int64_t max_age_ns = kDefaultTrackedMaxAgeNs);

enum class RpeDelta {
  kSeconds,  ///< delta is a time (s) between estimate stamps
  kMeters,   ///< delta is a ground-truth travelled distance (m)
};

struct RpeParams {
  double delta = 1.0;
  RpeDelta unit = RpeDelta::kSeconds;
  double rel_tol = 0.1;  ///< accepted |separation - delta| / delta
};

struct RelativePoseErrorStats {
  RpeParams params;
  ErrorStats translation_m;  ///< |E.p| (m); count = number of pairs
  ErrorStats rotation_deg;   ///< angle of E.R (deg)
};

/// The pairs (i, j) as indices into association.pairs (i < j). Throws
/// std::invalid_argument on delta <= 0 or rel_tol outside [0, 1), or an
/// estimate that is not in strictly increasing time order.
std::vector<std::pair<std::size_t, std::size_t>> rpePairs(const TumTrajectory& estimate,
                                                          const std::vector<GroundTruthPose>& truth,
                                                          const PoseAssociation& association, const RpeParams& params);

RelativePoseErrorStats relativePoseError(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                         const PoseAssociation& association, const RpeParams& params);

/// Travelled distance of the ground truth from its first pose to each pose (m).
std::vector<double> groundTruthPathLength(const std::vector<GroundTruthPose>& truth);

/// Everything `rilo eval` reports.
struct TrajectoryEvaluation {
  std::size_t estimate_poses = 0;
  std::size_t truth_poses = 0;
  PoseAssociation association;
  PositionErrorStats ape;
  RelativePoseErrorStats rpe_time;      ///< default: 1 s
  RelativePoseErrorStats rpe_distance;  ///< default: 10 m
};

struct EvaluationParams {
  std::int64_t max_dt_ns = kDefaultAssociationMaxDtNs;
  RpeParams rpe_time{1.0, RpeDelta::kSeconds, 0.1};
  RpeParams rpe_distance{10.0, RpeDelta::kMeters, 0.1};
};

/// Throws std::invalid_argument on bad parameters or an estimate out of time order.
TrajectoryEvaluation evaluateTrajectory(const TumTrajectory& estimate, const std::vector<GroundTruthPose>& truth,
                                        const EvaluationParams& params = {});

}  // namespace rilo
