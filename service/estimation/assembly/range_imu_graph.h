#pragma once
// Builds the Ranging-IMU Fusion paper's factor graph (Fig. 4) from raw samples: one state
// (pose, velocity, bias) per ranging time, ranges within a short window
// sharing a state; combined IMU preintegration factors between consecutive
// states; range factors with the configured robust loss; anchors as
// variables with survey priors (or constants); priors on the first state.
// Initial values are the caller's business (the pipeline's initializer, or a
// perturbed ground truth in tests and the demo).
#include <cstdint>
#include <string>
#include <vector>

#include "estimation/graph/factor.h"
#include "estimation/imu/imu_params.h"
#include "estimation/measurements/height_band.h"
#include "estimation/measurements/measurement.h"
#include "estimation/measurements/standstill.h"
#include "estimation/measurements/tdoa_model.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/noise/tdoa_gap_excess.h"
#include "estimation/measurements/tag_lever_arms.h"
#include "sensors/samples.h"

namespace rilo {

struct RangeImuGraphParams {
  ImuParams imu;
  std::string range_loss = "asymmetric";  ///< see makeRangeLoss
  RangeNoiseParams range_noise;
  /// Ranges closer than this share one state (>= 0): each is predicted
  /// where the state's velocity takes the tag by its own time
  /// (RangeTimeOffset). The service ships 50 ms (config/rilod.yaml): 40 Hz
  /// ranging then gives about 12 states a second instead of 35, which is
  /// what the smoother's cost scales with, and the motion left out over
  /// 50 ms (half the acceleration times dt^2, the lever arm's turn) stays
  /// under 1 cm (docs/smoother.md, "States per ranging epoch").
  std::int64_t same_state_window_ns = 5'000'000;
  /// Longest interval between consecutive states: ranging gaps get IMU-only
  /// states, so preintegration windows stay short (rotation, first-order bias).
  std::int64_t max_state_interval_ns = 500'000'000;
  bool anchors_as_variables = true;               ///< Ranging-IMU Fusion paper: anchors as variables with survey priors
  double anchor_sigma_m = 0.02;                   ///< survey std-dev of anchor positions (m)
  Vec3 p_b_tag = Vec3::Zero();                    ///< UWB antenna lever arm, body frame (m)
  /// Further antennas by tag id (tag_lever_arms.h): a range from a listed
  /// tag is predicted from its antenna, any other from p_b_tag. The height
  /// band, TDoA and the position-only fix keep p_b_tag.
  std::vector<TagLeverArm> tag_lever_arms;
  /// The antenna of a range's tag (m, body frame).
  const Vec3& leverArm(std::uint32_t tag_id) const { return leverArmOf(tag_lever_arms, tag_id, p_b_tag); }
  // Priors on the first state (around the initial guess).
  Vec6 first_pose_sigmas = (Vec6() << 0.1, 0.1, 0.5, 1.0, 1.0, 1.0).finished();  ///< [rad x3, m x3]
  double first_velocity_sigma_m_s = 1.0;
  double first_accel_bias_sigma = 0.1;   ///< m/s^2
  double first_gyro_bias_sigma = 0.01;   ///< rad/s
  // What a walking wearer's motion tells about height (architecture: poor
  // vertical geometry). Both off here; the Localizer turns them on.
  /// Soft band on the tag height of every state (HeightBandFactor on the body
  /// height, shifted by the lever arm's z for an upright wearer).
  HeightBand height_band = HeightBand::off();
  /// Std-dev of a zero-mean prior on the vertical velocity (m/s) of a state
  /// vertical_speed_correlation_s or more after the previous one; 0: none.
  /// Closer states share that information (verticalSpeedPriorSigma), so the
  /// prior's pull per second does not grow with the state rate.
  double vertical_speed_sigma_m_s = 0.0;
  /// Time (s) over which a walker's vertical speed is taken as one value: half
  /// a step cycle (about two steps a second), after which the gait's bob has
  /// turned. > 0.
  double vertical_speed_correlation_s = 0.25;
  /// Zero-velocity prior on each state that closes an interval the IMU shows
  /// still (StandstillDetector with `standstill`), sigma * sqrt(1 s / the
  /// interval) per state: the same weight per second at any ranging rate, as
  /// the initializer's (InitializerParams::zero_velocity_sigma_m_s). 0: none.
  double zero_velocity_sigma_m_s = 0.0;
  StandstillParams standstill;

  // UWB TDoA and ultrasonic ranging (IMU-Ultrasonic-UWB paper). TDoA uses the UWB anchors
  // (as variables or constants, like ranges); ultrasonic beacons are constants.
  /// Loss of TDoA factors (makeRangeLoss names). Symmetric by default: NLOS on
  /// either anchor of the pair biases the difference, with opposite signs.
  std::string tdoa_loss = "huber";
  double tdoa_sigma_m = 0.15;         ///< std-dev of a LOS range difference (m)
  /// Rows with receive diagnostics (tdoa_model.h): one packet flagged NLOS
  /// gets this loss, oriented; both flagged, tdoa_loss at the sigma times
  /// tdoa_both_flagged_sigma_factor. tdoa_nlos_indicator false: rows as unflagged.
  std::string tdoa_flagged_loss = "asymmetric";
  double tdoa_both_flagged_sigma_factor = 3.0;
  double tdoa_one_flagged_sigma_factor = 2.0;  ///< the EKF's (symmetric loss, no orientation)
  bool tdoa_nlos_indicator = true;
  /// Rows with a packet whose gap exceeds this are not used (dB; +inf: all
  /// used; TdoaModelParams::max_power_gap_db).
  double tdoa_max_power_gap_db = 15.0;
  /// Per gap bin NLOS excess of a packet, learnt from the rows' post-fit
  /// residuals and taken off each row (tdoa_gap_excess.h; needs
  /// tdoa_nlos_indicator; the graph estimators only, not the EKF).
  TdoaGapExcessParams tdoa_gap_excess;
  /// Loss of ultrasonic ranges: the asymmetric model, because reflections
  /// off furniture and people only ever lengthen the path (the IMU-Ultrasonic-UWB paper uses
  /// Huber; measured: docs/noise-models.md, Figures behind the defaults).
  std::string ultrasonic_loss = "asymmetric";
  double ultrasonic_sigma_m = 0.03;   ///< std-dev of a LOS ultrasonic range (m)
  Vec3 p_b_ultrasonic = Vec3::Zero(); ///< ultrasonic receiver lever arm, body frame (m)
  /// Ultrasonic beacons by anchor id (m, world); ids not in use hold any
  /// finite filler. Empty: no ultrasonic ranging.
  std::vector<Vec3> p_w_ultrasonic;
};

/// The TDoA model of params (tdoa_model.h).
TdoaModelParams tdoaModelParams(const RangeImuGraphParams& params);

/// Std-dev (m/s) of the vertical speed prior on a state interval_ns after the
/// previous one: vertical_speed_sigma_m_s * sqrt(tau / min(interval, tau)),
/// tau = vertical_speed_correlation_s (interval at least 1 ms). States closer
/// than tau split the prior's information, so 35 states a second and 12 pull
/// the same per second. The graph stream and the EKF baseline both use it.
double verticalSpeedPriorSigma(const RangeImuGraphParams& params, std::int64_t interval_ns);

struct RangeImuGraph {
  FactorGraph graph;
  std::vector<std::int64_t> state_t_ns;  ///< time of state i (keys X(i), V(i), B(i)); includes IMU-only states
  std::vector<Key> anchor_keys;          ///< L(anchor_id) for anchors used as variables
  std::size_t range_factors = 0;  ///< measurement factors of every kind (ranges, TDoA, ultrasonic)
  std::size_t imu_factors = 0;
  std::size_t motion_priors = 0;  ///< height band / vertical speed priors (last in the graph)
};

/// Builds the graph. `p_w_anchors[id]` is the surveyed position of anchor id;
/// `first_state` is the initial guess of state 0 (the priors' mean).
/// Throws std::invalid_argument when samples are unsorted, an anchor id is
/// unknown, or no IMU sample covers the ranging interval.
RangeImuGraph buildRangeImuGraph(const std::vector<ImuSample>& imu, const std::vector<RangeSample>& ranges,
                                 const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess,
                                 const Vec3& v_w0_guess, const RangeImuGraphParams& params);
/// The same from measurements of any kind (in time order; TDoA and ultrasonic
/// factors as RangeImuGraphStream makes them, ultrasonic beacons from
/// params.p_w_ultrasonic). Throws as above, and for a measurement the stream
/// refuses (unknown beacon, equal TDoA anchors, non-finite value).
RangeImuGraph buildRangeImuGraph(const std::vector<ImuSample>& imu, const std::vector<Measurement>& measurements,
                                 const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess,
                                 const Vec3& v_w0_guess, const RangeImuGraphParams& params);

}  // namespace rilo
