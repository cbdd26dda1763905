#pragma once
// Coarse range-inertial alignment: the initializer's answer to "which way is
// the device facing" (yaw is not observable from gravity).
//
// One strapdown integration of the raw IMU from the window start t_r
// (strapdown.h) predicts the antenna at every range time from the
// state at t_r (R_r, p_r, v_r) and a constant bias (b_a, b_g):
//   tag(t_j) = p_r + v_r dt + g_w dt^2 / 2 + R_r dp_j(b) + R_r dR_j(b) p_b_tag
// and a robust Levenberg-Marquardt fits those 15 unknowns to the
// measurements of the window, with priors on the biases, on the
// tilt (from gravity, with the gravity step's uncertainty), on the vertical
// velocity (a walking person) and the height band. The yaw of R_r is not
// observable until the device accelerates horizontally (starts walking,
// turns): the fit is started from `yaw_hypotheses` yaws evenly spread around
// the circle, the lowest cost wins, and the result reports the yaw's
// marginal sigma and the cost gap to the best solution with a distinct yaw,
// from which the initializer decides whether yaw is observable yet. This
// replaces "direction of the multilaterated velocity vs the IMU-integrated
// one": the same information, used in one consistent least-squares fit that
// also works with sparse (1 Hz) ranging, where no velocity can be
// differentiated from the fixes.
//
// Measurements of any kind (measurement.h), each a whitened residual
// r = (measured - predicted) / sigma of the antenna track:
//  - UWB range: |tag - A|, loss of range_loss.h (heavy NLOS tail on the
//    long side, Huber on the short side);
//  - UWB TDoA: |tag - A_b| - |tag - A_a|, the same long-side loss mirrored
//    (rho(|r|)): NLOS on either anchor of the pair biases the difference, with
//    opposite signs;
//  - ultrasonic range: |receiver - beacon| with the receiver's own lever arm,
//    as a range, at ultrasonic_sigma_m: a coarse sigma on purpose, because
//    the fit starts from a fix that can be decimetres off, where the
//    cm-accurate ranges at their own sigma would sit in the heavy tail and be
//    ignored (the batch solve after this uses their real sigma).
// The height band applies to the UWB antenna at UWB measurement times.
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "estimation/init/gravity.h"
#include "estimation/init/strapdown.h"
#include "estimation/measurements/height_band.h"
#include "estimation/measurements/measurement.h"
#include "estimation/measurements/tag_lever_arms.h"
#include "estimation/noise/robust_loss.h"
#include "math/imu_bias.h"
#include "math/pose3.h"
#include "sensors/samples.h"

namespace rilo {

struct AlignmentParams {
  double range_sigma_m = 0.15;           ///< LOS range std-dev (m)
  double tdoa_sigma_m = 0.15;            ///< LOS range-difference std-dev (m)
  double ultrasonic_sigma_m = 0.15;      ///< ultrasonic range std-dev of this coarse fit (m), see above
  Vec3 p_b_ultrasonic = Vec3::Zero();    ///< ultrasonic receiver lever arm, body frame (m)
  /// Ultrasonic beacons by id (m, world); ultrasonic ranges to ids beyond it are skipped.
  std::vector<Vec3> p_w_ultrasonic;
  RobustLossPtr long_side_loss;          ///< loss of too-long ranges; null: the asymmetric range loss at range_sigma_m
  double short_side_huber_k = 3.0;       ///< Huber threshold of too-short ranges (sigmas)
  Vec3 p_b_tag = Vec3::Zero();           ///< antenna lever arm, body frame (m)
  std::vector<TagLeverArm> tag_lever_arms;  ///< further antennas by tag id (RangeImuGraphParams::tag_lever_arms)
  double gravity_m_s2 = 9.81;
  double accel_bias_sigma = 0.1;         ///< prior std-dev of the accelerometer bias (m/s^2)
  double gyro_bias_sigma = 0.01;         ///< prior std-dev of the gyroscope bias (rad/s)
  HeightBand band;                       ///< on the antenna height at every range time
  /// Prior std-dev of the vertical velocity at t_r (m/s): a walking person's is
  /// small; +inf disables it.
  double vertical_velocity_sigma_m_s = 0.5;
  int yaw_hypotheses = 8;                ///< starting yaws, evenly spread over 2 pi
  int max_iterations = 50;               ///< per hypothesis
  double distinct_yaw_rad = 0.5;         ///< solutions whose yaws differ by more than this are distinct

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

/// A two-way range more than this many sigmas shorter than a solution
/// predicts is "short": NLOS cannot explain it (start-up's heavy-NLOS rule,
/// InitializerParams::heavy_nlos_after_s; the alignment and the batch alike).
inline constexpr double kShortRangeSigmas = 3.0;

struct AlignmentResult {
  bool valid = false;          ///< a finite solution exists (observability is judged by the caller)
  std::string message;
  std::int64_t t_ref_ns = 0;
  Pose3 T_w_b;                 ///< body pose at t_ref
  Vec3 v_w = Vec3::Zero();     ///< velocity at t_ref (m/s)
  ImuBias bias;                ///< constant bias over the window
  int measurements = 0;        ///< measurements used (every kind)
  int inliers = 0;             ///< |whitened residual| <= 3
  int ranges = 0;              ///< two-way ranges among the measurements
  int short_ranges = 0;        ///< two-way ranges more than kShortRangeSigmas shorter than the fitted track predicts
  double cost = std::numeric_limits<double>::infinity();  ///< robust cost incl. priors (whitened, ~chi^2/2)
  double measurement_cost = std::numeric_limits<double>::infinity();  ///< robust cost of the measurements only
  double yaw_sigma_rad = std::numeric_limits<double>::infinity();   ///< marginal sigma of the world yaw at t_r
  /// Marginal sigma of the world yaw at the newest measurement (end of the
  /// window): R(t) = R_r dR(t, b_g), so it carries the yaw at t_r and the
  /// gyro bias with their correlation. At t_r the gyro bias prior alone adds
  /// up to its sigma times the window length (0.01 rad/s over 30 s: 17 deg)
  /// that the fit cannot resolve; at the end the window's own motion pins it.
  double yaw_sigma_end_rad = std::numeric_limits<double>::infinity();
  double position_sigma_m = std::numeric_limits<double>::infinity();  ///< sqrt(trace) of p_r's covariance
  double second_cost_gap = std::numeric_limits<double>::infinity();   ///< cost of the best solution with a distinct yaw minus cost
  double moved_m = 0.0;            ///< largest horizontal distance of the fitted antenna track from its start (m)
  double horizontal_dv_m_s = 0.0;  ///< largest horizontal velocity change over the window (m/s)
  std::vector<double> hypothesis_costs;  ///< final cost per yaw hypothesis

  /// Scale of the fit's whitened residuals (1 when the data follow the
  /// nominal sigmas), from the share of them within 3: see noiseScaleFromInlierShare.
  double noiseScale() const;

  /// The fitted model evaluated at one strapdown delta (from the same t_r).
  StrapdownState at(const StrapdownDelta& d, double gravity_m_s2) const {
    return propagate(d, T_w_b, v_w, bias, gravity_m_s2);
  }
};

/// The s for which |N(0, s^2)| <= `bound` has probability inliers / total:
/// a residual scale that needs only a count (robust: the share is a median-like
/// statistic, NLOS tails beyond the bound weigh as much as any outlier).
/// The share is clamped to [0.5, P(|N(0, 1)| <= bound)], so s lies in
/// [1, bound / 0.6745]; 1 for total <= 0.
double noiseScaleFromInlierShare(int inliers, int total, double bound = 3.0);

/// Fits the model above to `measurements` (in time order; those before
/// t_ref_ns, with an unknown anchor or beacon, or a non-finite value are
/// skipped) given the IMU samples `imu`, the gravity alignment at t_ref
/// (roll/pitch start and tilt prior), and a guess of the antenna position and
/// velocity at t_ref (from multilateration or a TDoA fix). Never throws on data.
AlignmentResult alignRangeInertial(std::span<const ImuSample> imu, std::span<const Measurement> measurements,
                                   std::int64_t t_ref_ns, const std::vector<Vec3>& p_w_anchors,
                                   const GravityAlignment& gravity, const Vec3& p_w_tag_guess,
                                   const Vec3& v_w_guess, const AlignmentParams& params);
/// The same for two-way ranges only.
AlignmentResult alignRangeInertial(std::span<const ImuSample> imu, std::span<const RangeSample> ranges,
                                   std::int64_t t_ref_ns, const std::vector<Vec3>& p_w_anchors,
                                   const GravityAlignment& gravity, const Vec3& p_w_tag_guess,
                                   const Vec3& v_w_guess, const AlignmentParams& params);

}  // namespace rilo
