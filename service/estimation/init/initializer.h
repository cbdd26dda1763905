#pragma once
// Initialization without a known start (architecture "Estimation: Start-up",
// Ranging-IMU Fusion paper, Sec. V: a batch solve over the first 10 s, handed to the
// incremental smoother). Fed the same samples as the estimator, in time
// order; once the state is observable it returns a recent state of a
// batch-solved window (pose, velocity, bias; hand_over_later_measurements)
// and the window itself.
// Measurements of every kind count (measurement.h): UWB two-way ranges, UWB
// TDoA rows and ultrasonic ranges, alone or mixed; "ranges" below means any
// of them unless said otherwise.
//
// Each attempt (every attempt_interval_s of data once min_window_s is
// buffered) works on the newest window of data: window_s (the Ranging-IMU Fusion paper's 10 s;
// all the data at the first attempts), grown when ranging is sparse so that
// it holds min_window_ranges ranges, and grown up to max_window_s once
// window_s proved too short for yaw (a smooth walk: 0.2-0.4 m/s^2 of
// horizontal acceleration separate yaw from the accelerometer bias and tilt
// only after 15-20 s; a start from rest or a gait with steps does it in 3-4 s):
//  1. a fix of the antenna at the window start: multilateration of two-way
//     ranges (multilateration.h: robust, position + velocity over a
//     short window grown for sparse ranging, mirror solutions across the
//     anchor plane resolved by the height band), or, when the window has
//     none, the TDoA fix (tdoa.h: spherical intersection, consensus,
//     ultrasonic-enhanced; IMU-Ultrasonic-UWB paper, Sec. III-B; position only, the velocity
//     is left to step 3);
//  2. roll and pitch from gravity (gravity.h): a still interval at the
//     window start if there is one, else the gyro-compensated mean specific
//     force over the whole window (motion averages out; the tilt prior of the
//     next step is loosened accordingly);
//  3. yaw by range-inertial alignment (alignment.h): one strapdown
//     integration over the window, the window-start state and a constant bias
//     fitted to all ranges from 8 yaw hypotheses; yaw is observable once its
//     marginal sigma is small and no other yaw fits nearly as well (the device
//     has accelerated horizontally: started walking, turned); "nearly as
//     well" is judged in units of the data's own noise scale
//     (max_yaw_gap_noise_scale), not the nominal sigmas'. Chosen over the
//     "velocity direction vs IMU velocity" heuristic because it needs no
//     velocity from differentiated fixes and so also works at 1 Hz ranging;
//  4. the Ranging-IMU Fusion paper's batch: buildRangeImuGraph over the window (every kind of
//     measurement, the tracking estimator's factors) with the first
//     state's priors around the alignment, every state initialized from the
//     aligned strapdown track, zero-velocity priors on the states inside
//     still intervals of the IMU, batch Levenberg-Marquardt; accepted when it
//     converged, the range and IMU costs per factor are plausible, the
//     newest state's marginal position and yaw sigmas are small, and its tag
//     lies in the height band and near the anchors' horizontal box. The solve
//     is skipped (batch_gate_sigma_factor) while those sigmas, taken at the
//     starting values before any iteration, are well above the limits, and
//     not repeated on the same data after a rejection.
// Known limit (architecture "Known hard cases"): with 25 % persistent NLOS
// the window's height can be off by 0.3-0.9 m while the horizontal error
// stays below 0.3 m; the estimator started at the true state shows the same.
// Data problems never throw: bad samples are dropped and counted, and
// status() says why initialization is not possible yet.
//
// Memory: samples older than max_window_s (plus a margin) are dropped while
// not initialized. After initialization every sample from the result's state
// time on is kept for the hand-over (hand over promptly).
// Single-threaded. An attempt may run on a copy elsewhere while this one
// keeps buffering (attemptDue, adoptAttempt: the Localizer's init runner).
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "estimation/assembly/range_imu_graph.h"
#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/assembly/start_covariance.h"
#include "estimation/graph/values.h"
#include "estimation/init/alignment.h"
#include "estimation/init/gravity.h"
#include "estimation/init/multilateration.h"
#include "estimation/init/tdoa.h"
#include "estimation/measurements/anchor_box.h"
#include "estimation/measurements/height_band.h"
#include "estimation/measurements/measurement.h"
#include "estimation/solver/lm_params.h"
#include "estimation/solver/lm_result.h"
#include "sensors/samples.h"

namespace rilo {


struct InitializerParams {
  /// The estimator's graph parameters (IMU model, range loss and noise, lever
  /// arm, first-state priors, TDoA and ultrasonic settings and beacons): the
  /// batch window is built with them, and the small solvers take sigmas,
  /// lever arms, beacons, gravity and bias priors from them.
  /// The small solvers always use the asymmetric range loss (robust to NLOS
  /// whatever the graph's loss is).
  RangeImuGraphParams graph;

  double window_s = 10.0;          ///< batch window (s); the Ranging-IMU Fusion paper uses 10 s
  double min_window_s = 3.0;       ///< first attempt once this much data is buffered (s)
  /// The window grows up to this for sparse ranging (to hold
  /// min_window_ranges) and when window_s was too short for yaw (s). 45 s
  /// for 1 Hz ranging: with 30 s the newest state's yaw sigma stayed at
  /// 6-7 deg (> max_yaw_sigma_rad) on half the office/hall replays, which
  /// then never initialized in 120 s; with 45 s all seven did, 40 Hz
  /// unchanged (it rarely grows the window past window_s).
  double max_window_s = 45.0;
  int min_window_ranges = 40;      ///< measurements the window should hold (grown up to max_window_s for them)
  int min_alignment_ranges = 12;   ///< fewer measurements in the window: wait
  double attempt_interval_s = 0.5; ///< data time between attempts (s) ...
  /// ... grown by 1.5x after each attempt that failed at the (expensive) yaw
  /// alignment or batch solve, up to this (s): a device that keeps too still
  /// for yaw, or data that keeps failing, costs a bounded share of the CPU
  /// (and of a replay's time) rather than a full solve every half second.
  double max_attempt_interval_s = 1.0;

  /// A position-only fix of the newest ranges while the full state waits
  /// (provisional_fix.cpp), every this much measurement time (s; 0: off).
  double provisional_fix_interval_s = 0.5;
  /// Its window (s), grown by half up to provisional_fix_max_window_s until
  /// it holds enough anchors and measurements. Capped well below
  /// fix_max_window_s: a walker's constant-velocity fix over 8 s of 1 Hz
  /// ranging was 1.1 m off on average on the own sims (0.40 m at 40 Hz over 2 s).
  double provisional_fix_window_s = 2.0;
  double provisional_fix_max_window_s = 3.0;
  /// A provisional fix is published only when sound: inliers from at least
  /// 4 anchors (3 and the band leave a mirror) and at least this share of
  /// its ranges inliers. The fix's own floor (fix.min_inlier_fraction 0.5)
  /// let a 3 m-off streak through on the office sim (53 % inliers, a
  /// 3-anchor mirror, claimed sigma 0.1 m); the good fixes there had 72-85 %.
  double provisional_min_inlier_fraction = 0.7;
  double fix_window_s = 1.0;       ///< multilateration window (s) ...
  double fix_max_window_s = 8.0;   ///< ... grown up to this until it holds enough anchors and ranges (s)

  HeightBand height_band;          ///< tag height band (a wearable: 0.9-1.9 m above the floor z = 0)
  /// A batch window holding TDoA rows groups measurements closer than this
  /// into one state instead of graph.same_state_window_ns (ns; 0: the
  /// graph's window). LocalizerParams::with_tdoa sets it.
  std::int64_t tdoa_state_window_ns = 0;
  /// Multilateration settings; sigma_m, long_side_loss and band are set from graph / height_band.
  MultilaterationParams fix;
  /// TDoA fix settings (windows without two-way ranges); sigma_m,
  /// ultrasonic_sigma_m, ultrasonic_offset_m and band are set from graph /
  /// height_band. Its loss stays the mirrored asymmetric one (the fix's
  /// consensus was designed with it), whatever the graph's TDoA loss.
  TdoaFixParams tdoa_fix;
  GravityParams gravity;
  /// Alignment settings; range_sigma_m, long_side_loss, p_b_tag, gravity_m_s2,
  /// the bias sigmas and band are set from graph / height_band.
  AlignmentParams alignment;

  // Observability gates of the alignment (step 3).
  /// Yaw sigma at the window's end (~8 deg; AlignmentResult::yaw_sigma_end_rad):
  /// the newest state, which the batch hands over. At the window start the
  /// gyro bias prior dominates it (10-11 deg at 1 Hz ranging where the end
  /// has 6-8), so a start gate never opened within max_window_s at 1 Hz.
  double max_alignment_yaw_sigma_rad = 0.14;
  double min_yaw_cost_gap = 8.0;              ///< a distinct yaw within this cost is still plausible ...
  /// ... times s^2, s the alignment's noise scale (AlignmentResult::noiseScale)
  /// capped to this: costs are in nominal-sigma units, and data s times
  /// noisier than nominal inflate every cost, and the gap between two yaws,
  /// by s^2: on noisy data a wrong yaw could win by more than
  /// min_yaw_cost_gap. 1 disables. The cost: sparse ranging under heavy NLOS
  /// can fail to initialize (measured: docs/noise-models.md, Figures behind
  /// the defaults).
  double max_yaw_gap_noise_scale = 4.0;
  double max_alignment_cost_per_range = 3.0;  ///< per measurement; else they disagree with the IMU (wrong fix, bad data)

  /// Heavy NLOS. The cost gates (max_alignment_cost_per_range,
  /// max_range_cost_per_range) are in nominal-sigma units, and where most
  /// paths are blocked the right solution exceeds them: on `rilo sim
  /// --plan random --nlos-severity 2 / 3` with rilod.yaml (0.10 m sigma) the
  /// alignment's cost per range stayed at 3.6-4.4 and the batch's at 3.0-3.5
  /// for the whole two minutes, and the service never started. NLOS only
  /// lengthens a two-way range, so a right track leaves few ranges more than
  /// 3 sigma *shorter* than it predicts (the alignment: at most 1.5 % on every
  /// sim, clean or heavy; the batch: 0.5 % on random-plan severity 3), while
  /// a wrong fix, yaw or anchor survey leaves many (16-31 % with two anchors
  /// swapped or one moved 2 m); the same sign test as range_consistency.h.
  /// So once heavy_nlos_after_s of data has passed since the first two-way
  /// range (0: at once), a window whose measurements are mostly two-way
  /// ranges passes each cost gate up to heavy_nlos_cost_factor times its
  /// limit if at most max_short_range_share of its ranges are short.
  /// Not at once: windows that pass this way while a better one is to come
  /// start worse and stay worse (main sim rnd2, started at 13.8 s instead of
  /// 30.8 s: 0.43 m against 0.29 m online over the time both tracked).
  /// +inf: off.
  double heavy_nlos_after_s = 60.0;
  double max_short_range_share = 0.05;
  double heavy_nlos_cost_factor = 2.0;

  // Acceptance of the batch solve (step 4).
  /// Newest state, sqrt(trace) of the position covariance (m). Catches an
  /// unobservable position; at 1 Hz ranging the newest state's sigma is
  /// 0.4-0.9 m by nature (one range per second), at 40 Hz ~0.15 m.
  double max_position_sigma_m = 1.0;
  double max_yaw_sigma_rad = 0.087;     ///< newest state, world yaw (~5 deg)
  double max_range_cost_per_range = 2.5;  ///< mean robust cost of the measurement factors (every kind)
  /// The newest state's tag may lie at most this far (m) beyond the
  /// horizontal box of the surveyed UWB anchors (anchor_box.h; ultrasonic
  /// beacons do not count). Why: a wearer standing where three anchors, two
  /// of them on one wall, dominate has a mirror solution behind that wall
  /// that fits the ranges as well (held-out `rilo sim --plan random --seed
  /// 6`: accepted 1.2 m outside the box and 4 m from the truth, its last 2 s
  /// of ranges fitting at a cost of 0.46 per range, so no cost gate sees
  /// it); tracking stayed 4-6 m off for 5 s until the consistency check
  /// fired. Refused, it started 5 s later, inside (online error 0.46 ->
  /// 0.35 m). +inf disables: sites whose anchors cover only part of the
  /// walking area, with LocalizerParams::max_outside_anchors_m.
  double max_outside_anchors_m = 1.0;
  /// Mean cost of the IMU factors. At a sound optimum it is ~1e-3 (the
  /// per-state velocities and biases absorb the IMU noise); large values mean
  /// the states could not follow the IMU (time gaps, a broken model).
  double max_imu_cost_per_factor = 30.0;
  LmParams lm = defaultLmParams();
  /// Gate of the batch solve: the newest state's marginal position and yaw
  /// sigmas at the starting values (one factorization, no LM iterations)
  /// predict those at the solution; above this factor times
  /// max_position_sigma_m / max_yaw_sigma_rad the solve is skipped as it
  /// would be rejected. +inf disables (every attempt that passes the
  /// alignment solves).
  double batch_gate_sigma_factor = 1.15;
  /// ... but a solve runs at least every this much data time (s), whatever
  /// the prediction: a prediction that is off delays initialization by at
  /// most this much.
  double batch_gate_max_s = 4.0;
  /// Zero-velocity updates: batch states inside a still interval of the IMU
  /// (findStillIntervals) get a zero-velocity prior, sigma * sqrt(1 s / the
  /// state's interval) per state (the same weight per second at any ranging
  /// rate). What the IMU knows while the device rests: it pins the
  /// accelerometer bias that NLOS ranges would otherwise bend into a height
  /// drift. +inf disables.
  double zero_velocity_sigma_m_s = 0.05;

  /// The hand-over state: the newest batch state that at least this many of
  /// the window's measurements follow (0: the newest state); the tracker
  /// starts there and takes those measurements again (handOver). The newest
  /// state has only the last few measurements on its side: at 1 Hz ranging
  /// it can sit metres off while the states before it are within 0.5 m
  /// (rnd2 at a 0.10 m sigma: 0.3-0.5 m through the 45 s window, then 0.7,
  /// 1.6 and 3.3 m over its last 8 s, handed over claiming 0.19 m). 20
  /// lowers the 1 Hz online error; measured in docs/noise-models.md
  /// ("Figures behind the defaults").
  int hand_over_later_measurements = 20;
  /// ... only when ranging is sparse: the window's newest
  /// hand_over_later_measurements span more than this (s). Not by the newest
  /// state's sigma: the wrong one above claimed 0.19 m. At 40 Hz going back
  /// half a second cost 0.01 m (the start prior then counts those
  /// measurements twice), so dense ranging hands over the newest state.
  double hand_over_sparse_span_s = 2.0;
  /// The hand-over (handOver): the tracker's start priors are the hand-over
  /// state's marginals (pose, velocity, bias), conditioned by this
  /// (start_covariance.h); off, the graph's loose first-state priors.
  bool hand_over_covariance = true;
  StartCovarianceConditioning hand_over_conditioning;
  /// ... with the marginals first scaled by s^2, s the batch's residual scale
  /// (residualScale of the measurement factors' whitened residuals at the
  /// solution) clamped to [1, this]. The marginals assume the nominal sigmas,
  /// and blocked paths make the data noisier than that (s measured:
  /// docs/noise-models.md, Figures behind the defaults). 1 disables; the cap
  /// keeps one bad window from handing over a prior of metres.
  double max_hand_over_residual_scale = 4.0;

  /// The batch models two-way ranges the receiver flags as NLOS with the
  /// mixture (RangeNoiseParams::flagged_nlos_component off), whatever the
  /// graph's setting: its gates need every range's information, and the
  /// component (a wider flagged range, at its mode's shift: the batch has no
  /// excess estimate) kept sims at 1 Hz ranging from passing them
  /// (measured: docs/noise-models.md, "Ranges the receiver flags as NLOS").
  /// The tracker models them as configured.
  bool batch_flagged_mixture = true;

  double max_range_m = 500.0;  ///< ranges (two-way, ultrasonic) or |TDoA| beyond this (or negative ranges) are dropped as garbage (m)
  bool keep_window = true;     ///< keep the solved window in the result

  static LmParams defaultLmParams() {
    LmParams p;
    p.max_iterations = 50;
    p.relative_error_tolerance = 1e-7;
    p.record_trace = false;
    return p;
  }

  /// Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

enum class InitState {
  kWaitingForData,   ///< not enough data buffered (no IMU, no ranges, too short)
  kTooFewAnchors,    ///< fewer distinct anchors in the window than needed
  kPoorFix,          ///< multilateration failed its quality checks, or ranges disagree with the IMU
  kNoGravity,        ///< the accelerometer does not measure gravity
  kYawUnobservable,  ///< the device has not accelerated horizontally enough yet
  kBatchRejected,    ///< the batch solve failed its acceptance checks
  kInitialized,
};
const char* toString(InitState s);

struct InitStatus {
  InitState state = InitState::kWaitingForData;
  std::string message = "waiting: no samples";
  std::int64_t t_ns = 0;  ///< data time of the last attempt
  int attempts = 0;       ///< attempts so far (since construction or reset)
  int batch_solves = 0;   ///< attempts that got as far as the batch solve (the expensive step)
  int gated_solves = 0;   ///< batch solves skipped by the gate (batch_gate_sigma_factor)
};

/// Where the tag is while orientation, velocity and biases are not known yet:
/// a multilateration of the newest measurements (Initializer::provisionalFix).
struct ProvisionalFix {
  std::int64_t t_ns = 0;        ///< the newest measurement the fix holds
  Vec3 p_w_tag = Vec3::Zero();  ///< UWB antenna position (m, world)
  Mat3 cov_p_w = Mat3::Identity();  ///< its covariance (m^2): TagFix::cov_p_w, each anchor's ranges counted as one (provisional_fix.cpp)
  std::uint64_t sequence = 0;   ///< counts the fixes since construction (not reset): a new one has a new number
};

/// The batch-solved window, for a caller that seeds its smoother with it.
struct InitWindow {
  RangeImuGraph graph;  ///< as built (keys X/V/B(i) at graph.state_t_ns[i], anchors L(id))
  Values values;        ///< the batch solution
};

struct InitResult {
  StateEstimate state;              ///< the hand-over state (hand_over_later_measurements; index within the window graph)
  CovarianceBlock pose_covariance;  ///< marginal of state.T_w_b, tangent [rot; trans] (rad, m)
  /// The tracker's start priors (InitializerParams::hand_over_covariance):
  /// the marginals of state's pose, velocity and bias, conditioned; nullopt
  /// when off or a marginal was unavailable (then the graph's defaults).
  std::optional<StartCovariance> start_covariance;
  std::int64_t data_start_ns = 0;   ///< first accepted sample
  std::int64_t window_start_ns = 0; ///< first state of the window
  double time_to_init_s = 0.0;      ///< data time from data_start_ns to the successful attempt (s)
  TagFix fix;                       ///< the window-start fix (a TDoA fix converted: no velocity)
  bool fix_from_tdoa = false;       ///< the fix came from TDoA (and ultrasonic) rows
  GravityAlignment gravity;
  AlignmentResult alignment;
  LmResult lm;
  double range_cost_per_range = 0.0;  ///< per measurement factor of any kind
  /// Accepted above a normal cost gate, by the heavy-NLOS rule
  /// (InitializerParams::heavy_nlos_after_s).
  bool heavy_nlos = false;
  double residual_scale = 1.0;        ///< the measurement factors' residual scale at the solution (unclamped)
  double imu_cost_per_factor = 0.0;
  double still_s = 0.0;          ///< still time in the window (zero-velocity priors)
  std::optional<InitWindow> window;  ///< with InitializerParams::keep_window
};

class Initializer {
 public:
  /// `p_w_anchors[id]` is the surveyed position of anchor id (m, world).
  /// Throws std::invalid_argument for invalid params or anchors (not finite, none).
  Initializer(std::vector<Vec3> p_w_anchors, InitializerParams params = {});

  /// Buffers a sample; never throws on data: a sample that is not finite, not
  /// after the previous one (IMU), before the previous measurement (of any
  /// kind: measurements share one time order), for an unknown anchor or
  /// beacon, a TDoA row of one anchor with itself, or with an absurd value is
  /// dropped and counted.
  void addImu(const ImuSample& sample);
  void addRange(const RangeSample& sample) { addMeasurement(Measurement::of(sample)); }
  void addTdoa(const TdoaSample& sample) { addMeasurement(Measurement::of(sample)); }
  void addUltrasonic(const UltrasonicSample& sample) { addMeasurement(Measurement::of(sample)); }
  void addMeasurement(const Measurement& m);

  /// Runs an attempt when one is due (every attempt_interval_s of IMU time
  /// once min_window_s is buffered). Returns initialized().
  bool process();
  /// Runs an attempt now on what is buffered. Returns initialized().
  bool attempt();
  /// Whether process() would run an attempt now; refreshes the provisional
  /// fix and the waiting status as process() does. For a caller that runs
  /// attempts elsewhere: copy this initializer, call attempt() on the copy
  /// (on any thread) while this one keeps buffering, then adoptAttempt().
  bool attemptDue();
  /// Takes what an attempt on a copy of this initializer concluded: its
  /// status, its result, and the attempt schedule and window growth it
  /// chose. Keeps this one's samples (those that arrived meanwhile too), so
  /// a hand-over replays them. A result whose hand-over state is no longer
  /// buffered here (the attempt outlasted max_window_s of data) is dropped,
  /// and the status says so.
  void adoptAttempt(Initializer&& attempted);
  /// Attempts stop unfinished once *cancel reads true (checked between the
  /// steps and before each batch iteration): status kBatchRejected, "stopped
  /// unfinished", no result. nullptr: never. Not owned; copies share it.
  void setCancelFlag(const std::atomic<bool>* cancel);

  bool initialized() const { return status_.state == InitState::kInitialized; }
  /// The newest position-only fix since construction or reset, if any
  /// (provisional_fix_interval_s); it says nothing of orientation.
  const std::optional<ProvisionalFix>& provisionalFix() const { return provisional_; }
  const InitStatus& status() const { return status_; }
  /// Throws std::logic_error before initialization.
  const InitResult& result() const;
  /// Forgets everything (re-initialization after a failure).
  void reset();

  /// Buffered samples, in time order (the hand-over replays them).
  const std::vector<ImuSample>& imuBuffer() const { return imu_; }
  const std::vector<Measurement>& measurementBuffer() const { return meas_; }
  std::size_t droppedImu() const { return dropped_imu_; }
  std::size_t droppedMeasurements() const { return dropped_meas_; }
  const InitializerParams& params() const { return params_; }
  const std::vector<Vec3>& anchors() const { return p_w_anchors_; }

 private:
  /// The fix, gravity and alignment of one window, or why it is not usable.
  struct AlignedWindow {
    bool ok = false;
    InitState state = InitState::kWaitingForData;
    std::string message;
    std::size_t begin = 0, end = 0;  ///< meas_[begin, end)
    TagFix fix;
    bool fix_from_tdoa = false;
    /// No fix at any of the kFixStarts starts from the window's first
    /// measurement, meas_[begin], on (the window failed at step 1).
    bool fix_failed = false;
    GravityAlignment gravity;
    AlignmentResult alignment;
    bool heavy_nlos = false;  ///< the alignment passed its cost gate by the heavy-NLOS rule
  };

  void setStatus(InitState s, std::string message);
  bool cancelled() const { return cancel_ != nullptr && cancel_->load(std::memory_order_relaxed); }
  void trim();
  bool runAttempt();
  /// fix_max_window_s: how far the fix's own window may grow (step 1).
  AlignedWindow alignWindow(std::int64_t window_ns, std::int64_t t_now_ns, std::size_t end,
                            double fix_max_window_s) const;
  /// Fix from meas_[f0, f1): multilateration of its two-way ranges, else the TDoA fix.
  /// anchors_once: each anchor's ranges count as one in the fit's
  /// covariance (the published provisional fix, provisional_fix.cpp).
  TagFix fixOf(std::size_t f0, std::size_t f1, std::int64_t t_fix_ns, bool* from_tdoa, bool anchors_once = false) const;
  /// Distinct UWB anchors and ultrasonic beacons in meas_[begin, end).
  int sourcesHeard(std::size_t begin, std::size_t end) const;
  bool solveBatch(const AlignedWindow& w, std::int64_t t_now_ns);
  /// Largest distance between two UWB antennas on the body (m; 0 with one).
  double antennaSpreadM() const;
  /// A new provisional fix of the newest measurements when one is due.
  void updateProvisionalFix();
  /// Whether meas_[f0, f1) holds enough anchors and measurements for a fix.
  bool enoughForFix(std::size_t f0, std::size_t f1) const;
  /// A cost gate's limit times heavy_nlos_cost_factor when the heavy-NLOS
  /// rule applies to a window with these counts at t_now (params), else 1.
  double heavyNlosFactor(std::int64_t t_now_ns, int ranges, int short_ranges, int measurements) const;

  std::vector<Vec3> p_w_anchors_;
  InitializerParams params_;
  AnchorBox anchor_box_{p_w_anchors_};  ///< max_outside_anchors_m is judged against it

  std::vector<ImuSample> imu_;
  std::vector<Measurement> meas_;
  /// UWB anchors followed by the ultrasonic beacons (beacon id + p_w_anchors_.size()): the TDoA fix's one id space.
  std::vector<Vec3> p_w_fix_sources_;
  bool have_data_ = false;
  std::int64_t data_start_ns_ = 0;
  std::optional<std::int64_t> first_range_ns_;  ///< first two-way range since construction or reset (heavyNlosFactor)
  std::int64_t last_attempt_ns_ = 0;
  bool attempted_ = false;
  double interval_s_ = 0.5;   ///< current attempt interval (see max_attempt_interval_s)
  bool grow_window_ = false;  ///< window_s was not enough for yaw: use up to max_window_s
  /// Grown windows start no earlier than this (ns): the fix failed at every
  /// start before it (with the fix window that attempt allowed).
  std::optional<std::int64_t> no_fix_before_ns_;
  std::size_t dropped_imu_ = 0, dropped_meas_ = 0;
  const std::atomic<bool>* cancel_ = nullptr;  ///< setCancelFlag
  std::optional<std::int64_t> trimmed_before_ns_;  ///< trim() dropped the measurements before this (ns)

  /// What an attempt saw: the newest IMU time and the measurement buffer's size and newest time.
  struct InputStamp {
    std::int64_t t_imu_ns = 0;
    std::size_t measurements = 0;
    std::int64_t t_meas_ns = 0;
    bool operator==(const InputStamp&) const = default;
  };
  std::optional<InputStamp> rejected_input_;  ///< input of the last attempt whose batch was rejected
  bool batch_stage_reached_ = false;  ///< an attempt got as far as the batch since construction or reset
  std::int64_t last_batch_ns_ = 0;    ///< data time of the last batch solve that ran (or of the first attempt that got that far)

  InitStatus status_;
  std::optional<InitResult> result_;
  std::optional<ProvisionalFix> provisional_;
  std::uint64_t provisional_sequence_ = 0;
  std::optional<std::int64_t> provisional_tried_ns_;  ///< newest measurement of the last fix tried (published or not)
};

}  // namespace rilo
