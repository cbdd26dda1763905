#pragma once
// One deterministic run of the online pipeline (Localizer: initialization,
// smoother, recovery) over a recording, as fast as possible: what the service
// would have published at each time (online, causal), the final smoothed
// trajectory, per-update timing and counts. Shared by `rilo replay`,
// `rilo report` and the regression tests, so they all measure the same thing.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "estimation/tracking/localizer.h"
#include "evaluation/nlos_classification.h"
#include "evaluation/range_thinning.h"
#include "evaluation/trajectory_error.h"
#include "evaluation/covariance_consistency.h"
#include "evaluation/trajectory_metrics.h"  // positionErrorAgainst
#include "hal/recording/recording.h"

namespace rilo {

/// Which measurement kinds of a recording reach the Localizer.
struct MeasurementKinds {
  bool range = true;       ///< UWB two-way ranges (range.csv)
  bool tdoa = true;        ///< UWB TDoA rows (tdoa.csv)
  bool ultrasonic = true;  ///< ultrasonic ranges (ultrasonic.csv)
  bool operator==(const MeasurementKinds&) const = default;
};

/// Parses "range,tdoa,ultrasonic" (any non-empty subset, any order). Throws
/// std::invalid_argument naming an unknown kind or an empty list.
MeasurementKinds measurementKindsFromString(const std::string& list);
/// "range,tdoa,ultrasonic" (the selected kinds in that order).
std::string toString(const MeasurementKinds& kinds);


struct ReplaySettings {
  /// The service's parameters (rilod's configuration, `rilo replay
  /// --config`): the replay starts from them instead of the library defaults,
  /// so it runs the estimator rilod would run (not the vertical speed default
  /// below; the EKF's TDoA velocity noise stays, rilod has no EKF). The
  /// device is the recording's where its meta.yaml describes it
  /// (device_from_recording). smoother, noise and lag_s still apply (a caller
  /// sets them from the same configuration unless told otherwise), and so does
  /// every optional setting that is set.
  std::optional<LocalizerParams> service_params;
  /// With service_params: the IMU noise densities, the UWB and ultrasonic
  /// lever arms that the recording's meta.yaml gives, and its antennas
  /// (tags.csv), replace the configuration's (each one given; the rest, and
  /// gravity, stay the configuration's). The
  /// configuration describes the board rilod runs on, the recording the one
  /// that recorded it: the independent office sims (antenna at the body
  /// origin, a noisier accelerometer) replayed with rilod.yaml's 0.10 m arm
  /// and BMI263 densities were 0.08-0.2 m worse (docs/noise-models.md).
  /// false: the configuration's device throughout (a recording whose meta is
  /// known to be wrong).
  bool device_from_recording = true;
  std::string smoother = "d-isam2";  ///< d-isam2 | isam2 | dogleg | sliding-window | ekf
  std::string noise = "asymmetric";  ///< gaussian | huber | cauchy | asymmetric
  double range_hz = 0.0;             ///< thin ranges to this total rate (0: keep all)
  RangeThinning thinning = RangeThinning::kRotate;  ///< which ranges thinning keeps (range_thinning.h)
  double lag_s = 5.0;                ///< fixed lag of the smoother (s)
  // Range noise model (unset: the library defaults, RangeNoiseParams).
  std::optional<double> range_sigma_m;  ///< LOS range std-dev (m)
  std::optional<double> nlos_scale_m;   ///< half-Cauchy scale of the NLOS excess (m)
  std::optional<double> nlos_weight;    ///< prior NLOS probability
  std::optional<double> nlos_power_gap_db;  ///< receiver NLOS indicator threshold (dB; +inf: off)
  std::optional<double> flagged_nlos_weight;   ///< prior NLOS weight of flagged ranges
  std::optional<bool> flagged_nlos_component;   ///< flagged ranges: the NLOS component alone
  std::optional<double> flagged_nlos_scale_m;   ///< half-Cauchy scale of a flagged range's excess (m)
  std::optional<double> flagged_excess_quantile;  ///< FlaggedExcessParams::quantile (0: off)
  std::optional<bool> los_gap_calibration;        ///< LosGapParams::enabled
  std::optional<bool> rx_level_indicator;         ///< RxLevelEnvelopeParams::enabled
  std::optional<double> nlos_memory_s;            ///< NlosMemoryParams::window_s
  std::optional<double> range_error_correlation_s;  ///< RangeRepeatsParams::error_correlation_s (0: off)
  std::optional<double> max_outside_anchors_m;    ///< LocalizerParams::max_outside_anchors_m (+inf: off)
  std::optional<double> init_max_outside_anchors_m;  ///< InitializerParams::max_outside_anchors_m (+inf: off)
  std::optional<double> init_heavy_nlos_after_s;     ///< InitializerParams::heavy_nlos_after_s (+inf: off)
  // Height knowledge (unset: LocalizerParams defaults).
  std::optional<bool> height_band;             ///< soft tag height band on tracked states
  std::optional<double> floor_z_m;             ///< floor height in the world frame (m)
  std::optional<double> min_height_m, max_height_m;  ///< band above the floor (m)
  std::optional<bool> range_lever;             ///< HeightBand::range_lever
  std::optional<double> height_hold_sigma_m;   ///< HeightBand::hold_sigma_m (m per sqrt(s); 0: off)
  std::optional<bool> learn_carry_height;      ///< HeightBand::learn_carry_height
  /// Vertical speed prior (m/s; 0 none). Unset: kTdoaVerticalSpeedSigmaMs
  /// when TDoA rows are used, else kTwoWayVerticalSpeedSigmaMs.
  std::optional<double> vertical_speed_sigma_m_s;
  /// Zero-velocity prior at standstills (m/s per second still; 0 none).
  /// Unset: LocalizerParams' (or the service's) default.
  std::optional<double> zero_velocity_sigma_m_s;
  // Second system (IMU-Ultrasonic-UWB paper): TDoA, ultrasonic, packet reception.
  /// Kinds fed to the Localizer (default: every kind the recording has).
  MeasurementKinds measurements;
  /// Fraction of UWB packets kept, in [0, 1]: each TDoA epoch (the rows of
  /// one time: one received packet and its differences) and each range is
  /// kept with this probability, drawn in time order from reception_seed
  /// (deterministic). Ultrasonic ranges are not UWB packets: all kept.
  double reception = 1.0;
  std::uint64_t reception_seed = 1;
  /// Measurements closer than this share one state, for every kind of data
  /// (ms; unset: the Localizer's, 5 ms or, once the data hold TDoA rows,
  /// LocalizerParams::with_tdoa's 25 ms).
  std::optional<double> same_state_window_ms;
  /// Per-link TDoA and ultrasonic sigmas from DynamicCovariance. true: the
  /// graph stream and the EKF; false: neither; unset: both once the data
  /// hold TDoA rows (LocalizerParams::with_tdoa; the IMU-Ultrasonic-UWB paper's system; measured:
  /// docs/noise-models.md, Figures behind the defaults).
  std::optional<bool> dynamic_covariance;
  // TDoA and ultrasonic noise models (unset: RangeImuGraphParams defaults).
  std::optional<double> tdoa_sigma_m, ultrasonic_sigma_m;  ///< LOS std-dev (m)
  std::optional<std::string> tdoa_noise, ultrasonic_noise;  ///< loss names (makeRangeLoss)
  /// TDoA rows' receive diagnostics (tdoa_model.h; unset: RangeImuGraphParams
  /// defaults): whether they are used, the loss of a row with one packet
  /// flagged, and the sigma factors of the flagged rows.
  std::optional<bool> tdoa_nlos_indicator;
  std::optional<std::string> tdoa_flagged_noise;
  std::optional<double> tdoa_both_flagged_factor, tdoa_one_flagged_factor;
  /// Gap over which a TDoA row's packet is too deep in NLOS to use (dB; +inf:
  /// none; unset: RangeImuGraphParams::tdoa_max_power_gap_db).
  std::optional<double> tdoa_max_power_gap_db;
  /// Learn the packets' NLOS excess per gap bin and take it off the rows
  /// (graph estimators; unset: RangeImuGraphParams::tdoa_gap_excess.enabled).
  std::optional<bool> tdoa_gap_excess;
  /// Called now and then with the fraction of samples consumed (progress bars).
  std::function<void(double)> progress;
};

/// One smoother update, for timing.csv.
struct ReplayUpdate {
  std::int64_t t_ns = 0;  ///< time of the newest state after the update
  UpdateStats stats;
};

/// What happened to one measurement kind of the recording.
struct MeasurementCount {
  std::size_t recorded = 0;  ///< in the recording
  std::size_t used = 0;      ///< fed to the Localizer
  std::size_t dropped = 0;   ///< dropped by the simulated reception (ReplaySettings::reception)
  bool selected = true;      ///< in ReplaySettings::measurements (else none used, none dropped)
  /// TDoA: used rows with one / both packets flagged NLOS by their receive
  /// diagnostics (TdoaModel::flaggedPackets; 0 without diagnostics or with
  /// the indicator off), deep_nlos ones left out.
  std::size_t flagged_one = 0, flagged_both = 0;
  /// TDoA: used rows the Localizer dropped as too deep in NLOS
  /// (TdoaModel::gated, Localizer::tdoaRowsGated); part of `used`, which
  /// counts the rows fed to the Localizer.
  std::size_t deep_nlos = 0;
};

struct MeasurementCounts {
  MeasurementCount range, tdoa, ultrasonic;
};

struct ReplayResult {
  std::vector<RangeImuEstimator::TimedPose> online;    ///< newest state after each update
  /// The position-only fixes published while initializing
  /// (Localizer::provisionalPosition), in time order; their orientation is
  /// unknown (identity here). Kept apart from `online` so that orientation
  /// and relative-pose figures never read them; the online APE and tracked
  /// share count both, as the service publishes both.
  std::vector<RangeImuEstimator::TimedPose> position_only;
  std::vector<RangeImuEstimator::TimedPose> smoothed;  ///< final estimate of every state, time order
  /// What the service publishes with each online pose and position-only fix
  /// above, in time order: the position and its covariance (world; the
  /// tracker's marginal of the newest state, the fix's own covariance).
  /// Poses whose covariance was not available are left out.
  std::vector<TimedPositionCovariance> published_covariance;
  std::vector<ReplayUpdate> updates;
  /// Data time from the first sample to the first published position, and
  /// to the first full state (s; nullopt: none).
  std::optional<double> first_position_s, first_full_state_s;
  std::size_t ranges_used = 0;        ///< after --range-hz thinning and reception
  bool dynamic_covariance = false;    ///< the last tracker used per-link sigmas (Localizer::trackingDynamicCovariance)
  MeasurementCounts measurements;     ///< per kind: recorded, used, dropped
  std::uint64_t initializations = 0;
  std::uint64_t reinitializations = 0;
  std::uint64_t standstill_priors = 0;  ///< tracked states given the zero-velocity prior (Localizer::standstillPriors)
  InputDropCounts input_dropped;      ///< rows the physical screen dropped, by reason (Localizer::inputDropped)
  std::string last_failure;           ///< why tracking last ended, empty if never
  std::string init_status;            ///< the initializer's last message (why it has not started, if it never did)
  int init_attempts = 0;              ///< initialization attempts (all initializations)
  bool height_band_in_use = false;    ///< the tag height band held the tracked states
  std::string height_band_note;       ///< why a configured height band was dropped
  double flagged_excess_m = 0.0;      ///< final estimate of the flagged ranges' excess (Localizer::flaggedExcess)
  double nlos_gap_db = 0.0;           ///< final NLOS flag threshold of two-way ranges (Localizer::nlosGapDb; +inf: off)
  double flagged_scale_m = 0.0;       ///< half-Cauchy scale of flagged ranges when tracking last started (Localizer::trackingFlaggedScaleM)
  double data_s = 0.0;                ///< recording duration (IMU span, s)
  /// Share of the IMU span the online estimate covered (trackedShare): the
  /// APE figures are over those poses only.
  double online_tracked_share = 0.0;
  double wall_s = 0.0;                ///< time the run took (s)
  /// Present when the recording has ground truth.
  std::optional<PositionErrorStats> ape_online, ape_smoothed;
  /// Whether published_covariance covers the error (covariance_consistency.h;
  /// over every published pose, the position-only fixes included, as the
  /// online APE); with ground truth.
  std::optional<CovarianceConsistency> covariance_online;
  /// The same over the position-only fixes alone (the start's published positions).
  std::optional<CovarianceConsistency> covariance_position_only;
  /// Ranges the smoothed trajectory down-weights as NLOS (with the run's loss;
  /// scored against the recording's los column when it has one).
  NlosClassification nlos;

  double realtimeFactor() const { return wall_s > 0.0 ? data_s / wall_s : 0.0; }
};

/// Builds the Localizer parameters a replay of `rec` uses (IMU noise, lever
/// arms and ultrasonic beacons from the recording, smoother and noise model
/// from `settings`; from settings.service_params when given, see there).
LocalizerParams localizerParamsFor(const Recording& rec, const ReplaySettings& settings);

/// Runs the pipeline over `rec`. Throws std::runtime_error naming the
/// recording when it has no IMU samples or no measurement of a selected kind,
/// std::invalid_argument on bad settings.
ReplayResult replayRecording(const Recording& rec, const ReplaySettings& settings);

}  // namespace rilo
