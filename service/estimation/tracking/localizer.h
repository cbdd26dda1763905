#pragma once
// The whole online pipeline for one device: initialization from scratch
// (Initializer: multilateration, gravity alignment, batch window), hand-over
// to the incremental estimator, failure detection, and re-initialization.
// Used by rilod's estimator thread and by `rilo replay`; single-threaded, no
// I/O. Samples go in time order per stream; estimates come out after
// process(). With an init runner (setInitRunner: rilod), initialization
// attempts run elsewhere while the samples keep coming.
#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "estimation/ekf/ekf_params.h"
#include "estimation/graph/factor.h"
#include "estimation/init/initializer.h"
#include "estimation/measurements/anchor_box.h"
#include "estimation/measurements/input_screen.h"
#include "estimation/measurements/range_consistency.h"
#include "estimation/measurements/range_repeats.h"
#include "estimation/measurements/rx_level_envelope.h"
#include "estimation/measurements/tdoa_model.h"
#include "estimation/smoother/sliding_window_params.h"
#include "estimation/smoother/smoother_method_names.h"
#include "estimation/smoother/smoother_params.h"
#include "estimation/tracking/hand_over.h"
#include "estimation/tracking/init_attempt_runner.h"
#include "estimation/tracking/range_imu_estimator.h"
#include "estimation/tracking/ranging_support.h"
#include "estimation/tracking/rejection_window.h"
#include "estimation/tracking/tracking_estimator.h"

namespace rilo {

/// Vertical speed prior of every estimator when TDoA rows are used and no
/// value is given (rilo replay --vertical-speed-sigma, rilod's "auto"; m/s). Why: TDoA anchors on walls at
/// similar heights (2.0-2.8 m in the sims) leave the height weakly observable
/// and the NLOS-biased differences (97-99 % of the office sims' rows) pull it
/// around; a walking wearer on one floor keeps v_z near 0 (the sims' 2 cm step
/// bob: |v_z| <= 0.23 m/s). Measured in docs/noise-models.md ("Figures
/// behind the defaults"), as 0.05 per state at 40 states a second: 0.016 per
/// correlation time (RangeImuGraphParams::vertical_speed_correlation_s, 0.25 s)
/// is the same prior there (verticalSpeedPriorSigma). Stairs or lifts: pass 0 (off).
inline constexpr double kTdoaVerticalSpeedSigmaMs = 0.016;
/// Vertical speed prior of every estimator on two-way ranges when no value is
/// given: loose, about the size of a walker's own vertical speed (the sims'
/// step bob reaches 0.23 m/s), so it takes little from a step or a sit-down
/// that the IMU sees (localizer_test's sit-down), but the many states
/// together hold the height still where the ranges alone let it wander
/// across the height band (anchors at
/// similar heights: a common NLOS excess e looks like a height change of
/// about e / 0.2). Its pull per second is the same at any state rate above
/// one per correlation time (verticalSpeedPriorSigma): 0.1 per 0.25 s is
/// 0.32 per state at 40 states a second, the 0.3 per state measured in
/// docs/noise-models.md ("A loose vertical speed prior on two-way ranges")
/// when every 40 Hz range had its own state. Not stiffer: stiffer priors
/// ended tracking once on a walk outside a one-sided anchor layout
/// (localizer_test's TrackingFarOutsideTheAnchorsIsAFailure). TDoA keeps its
/// stiffer prior.
inline constexpr double kTwoWayVerticalSpeedSigmaMs = 0.1;
/// The vertical speed prior "auto" stands for: kTdoaVerticalSpeedSigmaMs with
/// TDoA rows, else kTwoWayVerticalSpeedSigmaMs.
inline double defaultVerticalSpeedSigma(bool tdoa_used) {
  return tdoa_used ? kTdoaVerticalSpeedSigmaMs : kTwoWayVerticalSpeedSigmaMs;
}

struct LocalizerParams {
  /// What tracks after initialization: the factor graph with a Bayes-tree
  /// smoother (method in `smoother`), the factor graph with the sliding-window
  /// LM smoother (IMU-Ultrasonic-UWB paper), or the error-state EKF baseline.
  enum class Estimator { kSmoother, kSlidingWindow, kEkf };
  Estimator estimator = Estimator::kSmoother;
  RangeImuGraphParams graph;
  SmootherParams smoother;           ///< method: D-iSAM2 (default), iSAM2, dog-leg
  SlidingWindowParams sliding_window;  ///< window_s follows smoother.lag_s when set by name
  EkfParams ekf;                     ///< gates and robust iterations (its IMU model is graph.imu)
  InitializerParams init;            ///< init.graph is replaced by `graph`
  RangeImuStreamOptions stream;
  /// What the deployment knows about the tag's height: used by the initializer
  /// and, when track_height_band is set, on every tracked state (overrides
  /// init.height_band and graph.height_band).
  HeightBand height_band;
  bool track_height_band = true;
  /// Vertical speed prior on every state (m/s; 0: none), see
  /// RangeImuGraphParams. Unset ("auto"): none in the initializer, and on the
  /// tracked states kTdoaVerticalSpeedSigmaMs when the data that started
  /// tracking hold TDoA rows, else kTwoWayVerticalSpeedSigmaMs
  /// (defaultVerticalSpeedSigma).
  std::optional<double> vertical_speed_sigma_m_s;
  /// Zero-velocity prior on each tracked state the IMU shows still (m/s per
  /// second of standstill; 0: none), RangeImuGraphParams::zero_velocity_sigma_m_s
  /// (overrides graph's; the initializer keeps its own). The initializer's
  /// value: wearers stop, and their stops held 23-63 % of the squared online
  /// error on the office sims (docs/noise-models.md, "Standstill").
  double zero_velocity_sigma_m_s = 0.05;
  /// Settings for data with UWB TDoA rows (the IMU-Ultrasonic-UWB paper's system), applied when
  /// the data a batch window (initializer) or the tracker starts on hold
  /// TDoA rows, so that one configuration serves both ranging schemes.
  struct WithTdoa {
    /// Measurements closer than this share one state, instead of
    /// graph.same_state_window_ns (ns; 0: keep that). A TDoA round of 8
    /// anchors is 8 packets 6.25 ms apart: 40 states a second instead of
    /// 160; each row is predicted at its own time (RangeTimeOffset). 50 ms
    /// replayed 1.2-1.7x faster but less accurately (docs/smoother.md,
    /// session 41). With the graph's 5 ms the office TDoA sims replayed at 3.4x real
    /// time and 0.46 m online error, against 27x and 0.35 m. Below
    /// graph.max_state_interval_ns. The range-consistency monitor follows
    /// the tracker's window (trackingStateWindowNs).
    std::int64_t state_window_ns = 25'000'000;
    /// Per-link TDoA and ultrasonic sigmas from their residuals
    /// (stream.dynamic_covariance and ekf.dynamic_covariance on; false: as
    /// they say): the office sims' NLOS TDoA errors are 1.3-1.5 m against a
    /// nominal 0.15 m.
    bool dynamic_covariance = true;
  };
  WithTdoa with_tdoa;
  // Failure detection: any of these ends tracking and restarts initialization.
  double max_speed_m_s = 10.0;       ///< a walking/running person stays well below
  double max_accel_bias_m_s2 = 1.5;  ///< far beyond a BMI263's bias range
  double max_gyro_bias_rad_s = 0.3;
  double max_imu_gap_s = 1.0;        ///< IMU silence longer than this: the motion model is broken
  /// Rows no sensor can produce, dropped and counted before anything else (input_screen.h).
  InputScreenParams screen;
  /// Horizontal distance (m) the tag may be estimated beyond the bounding box
  /// of the UWB anchors while ranging holds the estimate (ranging_support.h:
  /// judged only after 5 s of ranging without a gap over 3 s); +inf: off. Far outside, the ranging geometry
  /// degenerates (range differences approach the anchor baselines, whatever
  /// the distance), so a tracker that wanders there is held by nothing and
  /// its residuals stay small: office TDoA seed 6 at 40 % reception drifted
  /// to 16 m beyond the anchors at 2 m/s with at most 33 % of its rows 3 m off.
  double max_outside_anchors_m = 10.0;
  int max_consecutive_rejections = 40;  ///< D-iSAM2 updates keeping the previous estimate in a row
  /// Too many two-way ranges much shorter than the estimate predicts (see range_consistency.h).
  RangeConsistencyParams range_consistency;
  /// The typical excess of ranges the receiver flags as NLOS, estimated from
  /// their residuals at the tracked pose and taken off them (range_model.h).
  FlaggedExcessParams flagged_excess;
  /// The flag threshold of two-way ranges learnt from their residuals by gap
  /// (los_gap_calibration.h); never above range_noise.nlos_power_gap_db for
  /// the receiver's own gaps, up to los_gap.rx_level_max_gap_db for RX-level ones.
  LosGapParams los_gap;
  /// Where a two-way range carries the RX level but no first-path power, the
  /// NLOS indicator is its deficit below the learnt LOS path-loss envelope
  /// (rx_level_envelope.h), placed on the gap scale at the LOS reference of
  /// the threshold calibration (los_gap.min_gap_db + deficit, see
  /// withRxLevelIndicator) and judged like the receiver's gap. enabled =
  /// false: such ranges go unflagged.
  RxLevelEnvelopeParams rx_level_envelope;
  /// Where a two-way range carries no first-path power: an anchor whose last
  /// two ranges the mixture took as NLOS has its next one flagged
  /// (nlos_memory.h; the asymmetric model with a finite flag threshold only).
  NlosMemoryParams nlos_memory;
  /// Tracking weighs each two-way range by one over its anchor's ranges
  /// within the error's correlation time (range_repeats.h; 0, the default:
  /// off). The smoothers' tracking only: the initializer's batch and the EKF
  /// baseline take every range alone.
  RangeRepeatsParams range_repeats;
  /// Windowed rejection share (RejectionWindow, see its notes for the
  /// measurements behind the defaults): fail when more than
  /// max_rejection_share of the last rejection_window updates were rejected.
  /// Catches a diverged EKF that a lucky accepted group now and then keeps
  /// clear of max_consecutive_rejections. rejection_window 0: off.
  int rejection_window = 100;
  double max_rejection_share = 0.5;
  /// With an init runner (Localizer::setInitRunner): wall time (s) an
  /// attempt may run before it is told to stop unfinished; the next one
  /// starts on newer data at the usual interval. Why a bound: an attempt's
  /// result must be caught up with every sample that came meanwhile, and a
  /// solver that crawls must not hold initialization for good. An attempt on
  /// a 45 s window takes 0.1-1.3 s here (heavy NLOS the most), so 15 s leaves
  /// room for a core ten times slower. +inf: no bound.
  double init_attempt_budget_s = 15.0;

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

/// The names `rilo replay --smoother` takes: the smoother methods, "sliding-window" and "ekf".
const std::vector<std::string>& estimatorNames();
/// Sets params.estimator (and params.smoother.method) from one of estimatorNames().
void setEstimatorByName(LocalizerParams& params, const std::string& name);

class Localizer {
 public:
  enum class Phase { kInitializing, kTracking };

  /// `p_w_anchors[id]`: surveyed anchor positions (m, world).
  Localizer(std::vector<Vec3> p_w_anchors, LocalizerParams params);
  /// Waits for an attempt still running in the init runner.
  ~Localizer();
  Localizer(const Localizer&) = delete;
  Localizer& operator=(const Localizer&) = delete;

  /// Initialization attempts run in `runner` from now on: process() starts
  /// one on a copy of the buffered data when it is due, returns at once, and
  /// takes its outcome at the first call after the runner is idle (the
  /// tracker then starts at the attempt's state and catches up with every
  /// sample buffered since). Without a runner (the default: `rilo replay`,
  /// which must give the same figures on every run) attempts run inside
  /// process(). Call before the first sample.
  void setInitRunner(std::unique_ptr<InitAttemptRunner> runner);

  void addImu(const ImuSample& sample);
  void addRange(const RangeSample& sample);
  /// TDoA rows and ultrasonic ranges (beacons in params.graph.p_w_ultrasonic),
  /// alone or with two-way ranges: the initializer and the tracking
  /// estimator use every kind. Unknown anchors and beacons are skipped, and
  /// so are TDoA rows too deep in NLOS (TdoaModel::gated): addTdoa returns
  /// whether the row was taken.
  bool addTdoa(const TdoaSample& sample);
  void addUltrasonic(const UltrasonicSample& sample);
  /// Runs what is ready: an initialization attempt, or smoother updates.
  /// Appends one UpdateStats per smoother update when `stats` is given.
  /// Returns the number of smoother updates.
  int process(std::vector<UpdateStats>* stats = nullptr);
  /// No more samples (end of a recording): lets the last ranges through.
  /// With an init runner, waits for a running attempt (within its budget)
  /// and takes it; no attempt starts after this.
  void finish();

  Phase phase() const { return phase_; }
  bool tracking() const { return phase_ == Phase::kTracking; }
  /// Newest smoothed state; valid while tracking.
  const StateEstimate& latest() const { return estimator_->latest(); }
  /// Marginal covariance of the newest pose, tangent [rot; trans], if available.
  std::optional<CovarianceBlock> latestPoseCovariance();
  /// Marginal covariance of the newest velocity (world, m^2/s^2), if available.
  std::optional<CovarianceBlock> latestVelocityCovariance();
  const InitStatus& initStatus() const { return initializer_.status(); }
  const TrackingEstimator* estimator() const { return estimator_.get(); }
  /// Current estimate of the flagged ranges' excess (m; FlaggedExcessParams), 0 before there is one.
  double flaggedExcess() const { return flagged_excess_m_; }
  /// The two-way ranges' NLOS flag threshold in use (dB; LosGapParams).
  double nlosGapDb() const { return consistency_.flagGapDb(); }
  /// While initializing, the body position of the initializer's newest
  /// provisional fix (Initializer::provisionalFix), nullopt while tracking or
  /// before a fix. Orientation is unknown: the wearer is taken upright (the
  /// lever arm's z is taken off the antenna's height) and the lever arm's
  /// horizontal part, of unknown direction, widens the covariance.
  struct ProvisionalPosition {
    std::int64_t t_ns = 0;
    Vec3 p_w_b = Vec3::Zero();  ///< body position (m, world)
    Mat3 cov_p_w = Mat3::Identity();  ///< m^2
    std::uint64_t sequence = 0;  ///< ProvisionalFix::sequence: a new fix has a new number
  };
  std::optional<ProvisionalPosition> provisionalPosition() const;
  /// The RX-level indicator's envelope (fitted() false: not in use yet).
  const RxLevelEnvelope& rxLevelEnvelope() const { return rx_level_envelope_; }
  /// Ranges flagged as NLOS by their anchor's memory so far (nlos_memory.h).
  std::uint64_t rangesFlaggedByMemory() const { return ranges_flagged_by_memory_; }
  /// The smoothed trajectory so far (see TrackingEstimator::drainSmoothed);
  /// nothing while initializing.
  void drainSmoothed(std::vector<TimedPose>& out, bool all = false) {
    if (estimator_) estimator_->drainSmoothed(out, all);
  }

  /// An attempt is running in the init runner.
  bool initAttemptRunning() const { return pending_ != nullptr; }
  /// Tells a running attempt to stop, waits for it and drops it (a stop
  /// request: the attempt's outcome is not wanted).
  void abandonInitAttempt();
  /// Attempts told to stop unfinished, over init_attempt_budget_s.
  std::uint64_t initAttemptsOverBudget() const { return init_attempts_over_budget_; }

  std::uint64_t initializations() const { return initializations_; }
  std::uint64_t reinitializations() const { return reinitializations_; }
  /// TDoA rows dropped on arrival for a packet deeper in NLOS than
  /// graph.tdoa_max_power_gap_db (TdoaModel::gated).
  std::uint64_t tdoaRowsGated() const { return tdoa_rows_gated_; }
  /// Tracked states given the zero-velocity prior, over every tracking run.
  std::uint64_t standstillPriors() const {
    return standstill_priors_ended_ + (estimator_ ? estimator_->standstillPriors() : 0);
  }
  /// Rows the physical screen dropped, by reason, and the IMU time jumps it confirmed.
  const InputDropCounts& inputDropped() const { return screen_.dropped(); }
  /// Why the configured height band was dropped (empty when in use or never configured).
  const std::string& heightBandNote() const { return height_band_note_; }
  /// The parameters in effect (after the height band was resolved).
  const LocalizerParams& params() const { return params_; }
  /// The tracker's vertical speed prior (m/s; 0: none): the configured one,
  /// or what "auto" chose when tracking last started.
  double trackingVerticalSpeedSigma() const { return tracking_vertical_speed_sigma_m_s_; }
  /// Whether the tracker started last uses per-link TDoA/ultrasonic sigmas
  /// (the graph stream's or the EKF's dynamic covariance, as configured or
  /// by with_tdoa); false before the first tracking.
  bool trackingDynamicCovariance() const { return tracking_dynamic_covariance_; }
  /// The tracker's state window (ns): graph.same_state_window_ns, or with_tdoa's on TDoA data.
  std::int64_t trackingStateWindowNs() const { return tracking_state_window_ns_; }
  /// The range noise the tracker started last models two-way ranges with:
  /// graph.range_noise, with flagged_nlos_scale_m set for the two-way
  /// ranging rate it started on unless configured
  /// (RangeNoiseParams::flaggedComponentScaleAt); graph.range_noise before
  /// the first tracking.
  const RangeNoiseParams& trackingRangeNoise() const { return tracking_range_noise_; }
  /// Its half-Cauchy scale (m) for ranges the receiver flags as NLOS; 0 before the first tracking.
  double trackingFlaggedScaleM() const {
    return tracking_started_ ? tracking_range_noise_.flagged().nlosScaleM() : 0.0;
  }
  /// Why tracking last ended ("speed 14.2 m/s at t=12.3 s"), empty if never.
  const std::string& lastFailure() const { return last_failure_; }

 private:
  /// sample with the RX-level indicator as its first-path power where the
  /// receiver reported none (and the envelope is fitted), marked
  /// fp_from_rx_level; else sample. Such a flag says a path is attenuated,
  /// not by how much it is delayed: on the independent office sims the
  /// ranges it leaves unflagged carry as much excess as those it flags
  /// (+0.34 against +0.32 m), and a quantile of the flagged residuals,
  /// measured at a pose that the unflagged excess already biased, kept the
  /// height low. So its ranges take the NLOS component's mode (or their gap
  /// bin's excess), never the site's flagged excess, which is learnt from the
  /// receiver's own flags alone (range_model.h, range_consistency.h).
  /// Measured: docs/noise-models.md, session 31.
  RangeSample withRxLevelIndicator(const RangeSample& sample);
  /// sample marked nlos_from_memory where the receiver reported no
  /// first-path power (`received`) and the anchor's memory says NLOS
  /// (nlos_memory.h); else sample.
  RangeSample withNlosMemory(const RangeSample& received, RangeSample sample) const;

  /// With an init runner: takes a finished attempt's outcome, or starts one
  /// when due. Returns whether the initializer is now initialized.
  bool initializeElsewhere();
  void startTracking();
  void checkHealth(const UpdateStats& stats);
  void checkConsistency();
  /// Horizontal distance (m) of p_w beyond the anchors' bounding box, 0 inside.
  void fail(std::string why);
  template <typename F>
  void guarded(F&& f);

  std::vector<Vec3> p_w_anchors_;
  std::string height_band_note_;  // before params_: filled while params_ is resolved
  LocalizerParams params_;
  Phase phase_ = Phase::kInitializing;
  TdoaModel tdoa_model_;  ///< gates deep-NLOS TDoA rows on arrival
  std::uint64_t tdoa_rows_gated_ = 0;
  Initializer initializer_;
  std::unique_ptr<TrackingEstimator> estimator_;
  RangeConsistencyMonitor consistency_;
  /// The site's LOS path-loss envelope: kept over re-initializations (the
  /// building and the hardware stay).
  RxLevelEnvelope rx_level_envelope_;
  InputScreen screen_;
  bool estimate_flagged_excess_ = false;
  double flagged_excess_m_ = 0.0;
  std::uint64_t ranges_flagged_by_memory_ = 0;
  double gap_db_in_use_ = 0.0;  ///< last threshold handed to the estimator
  double tracking_vertical_speed_sigma_m_s_ = 0.0;
  std::uint64_t standstill_priors_ended_ = 0;  ///< of the tracking runs that ended
  bool tracking_dynamic_covariance_ = false;
  std::int64_t tracking_state_window_ns_ = 0;
  RangeNoiseParams tracking_range_noise_;
  bool tracking_started_ = false;
  AnchorBox anchor_box_{p_w_anchors_};  ///< horizontal bounding box of the UWB anchors
  RangingSupport ranging_support_;  ///< when max_outside_anchors_m is judged
  std::int64_t last_imu_ns_ = 0;
  bool have_imu_ = false;
  int consecutive_rejections_ = 0;
  std::optional<RejectionWindow> rejection_window_;  ///< empty when params_.rejection_window == 0
  std::uint64_t initializations_ = 0;
  std::uint64_t reinitializations_ = 0;
  std::string last_failure_;
  std::vector<UpdateStats> scratch_;

  /// An attempt in the init runner: on a copy of initializer_, told to stop by `cancel`.
  struct PendingAttempt {
    explicit PendingAttempt(const Initializer& buffered) : initializer(buffered) {}
    Initializer initializer;
    std::atomic<bool> cancel{false};
    std::chrono::steady_clock::time_point started = std::chrono::steady_clock::now();
  };
  std::unique_ptr<InitAttemptRunner> init_runner_;
  std::unique_ptr<PendingAttempt> pending_;  ///< after init_runner_: destroyed first (the destructor waits)
  std::uint64_t init_attempts_over_budget_ = 0;
  bool finished_ = false;  ///< finish() was called: no new attempt in the runner
};

}  // namespace rilo
