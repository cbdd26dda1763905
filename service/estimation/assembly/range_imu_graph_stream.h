#pragma once
// The Ranging-IMU Fusion paper's range + IMU factor graph (Fig. 4) delivered state by state
// as samples arrive: what an incremental smoother consumes in real time.
// buildRangeImuGraph (range_imu_graph.h) is this stream fed with complete
// sample vectors, so both build the same graph.
//
// States (same rules as the batch builder):
// - state 0 at the start time t0 given to start();
// - a range farther than same_state_window_ns after the newest state opens a
//   new state at its own time; closer ones join that state's ranging group;
// - a ranging gap longer than max_state_interval_ns gets evenly spaced
//   IMU-only states: pieces = ceil(gap / max), state j at t_prev + floor(gap j / pieces).
//
// When a state is emitted (next()): IMU samples cover its time (one at or
// after it, so the zero-order hold up to it is final) and its ranging group is
// closed (a later state exists, IMU time is past t + same_state_window_ns, or
// finish() was called).
//
// IMU-only gap states: their times depend on the time of the range that ends
// the gap, so no amount of IMU data fixes them earlier; the stream waits for
// that range. To bound the wait (IMU buffer and the smoother's latency during
// a ranging outage), once IMU time runs more than options.max_range_wait_ns
// past the newest state without a range, the stream commits an IMU-only state
// at newest + max_state_interval_ns and keeps waiting from there; the gap left
// when ranging resumes is split evenly as above. Ranging gaps up to
// max_range_wait_ns therefore give exactly the batch states; longer ones give
// states max_state_interval_ns apart, then an even split of the remainder.
// kWaitForever reproduces the batch states for any gap (the batch builder's
// setting) at the price of buffering IMU over the whole gap.
//
// Ranges of a state arrive after the state itself only for state 0 (start()
// returns its increment before any range) and for a range that arrives after
// IMU time already closed its group (a late range). They are delivered, once
// that group is closed, with the next state's increment if it is ready, or
// else in a ranges-only increment (new_state == false): the same factors as the
// batch graph, only in another update.
//
// Memory: IMU samples older than the one in effect at the last emitted state
// are dropped; buffers are growing rings (no allocation once they have grown
// to the working size: about one state interval of IMU, or max_range_wait_ns
// during an outage). Samples added before start() are all kept until start()
// (a bounded warm-up, e.g. the initializer's window), and nothing is emitted
// unless next() is called: the caller drives it after every add.
// Single-threaded: the caller serializes all calls.
#include <cstdint>
#include <limits>
#include <optional>
#include <utility>
#include <vector>

#include "estimation/assembly/measurement_noise.h"
#include "estimation/assembly/range_imu_graph.h"
#include "estimation/assembly/start_covariance.h"
#include "estimation/graph/factor.h"
#include "estimation/imu/preintegration.h"
#include "estimation/imu/state_estimate.h"
#include "estimation/measurements/carry_height.h"
#include "estimation/measurements/growing_ring.h"
#include "estimation/measurements/measurement.h"
#include "estimation/measurements/range_model.h"
#include "estimation/measurements/range_repeats.h"
#include "sensors/samples.h"

namespace rilo {

/// What one smoother update receives.
struct GraphIncrement {
  /// New factors, in this order: the priors on X0, V0, B0 (state 0 only); the
  /// combined IMU factor into the new state (new states i > 0); `range_factors`
  /// range factors in arrival order (late ones on the previous state first);
  /// one survey prior per new_anchor_keys entry (anchors as variables only);
  /// the new state's motion priors (height band, vertical speed, zero
  /// velocity at a standstill) when enabled.
  FactorGraph factors;
  Values values;  ///< initial values of every new key (new state's X, V, B; new anchors)
  std::vector<std::pair<Key, std::int64_t>> key_times_ns;  ///< time of every new state key (X, V, B); anchors have none
  std::vector<Key> new_anchor_keys;  ///< L(id) first ranged in this increment (value at the survey position)
  bool new_state = true;        ///< false: a ranges-only increment on the existing state `state_index`
  std::uint64_t state_index = 0;  ///< the new state (or the state a ranges-only increment ranges)
  std::int64_t t_ns = 0;          ///< time of state_index (ns)
  /// Measurement factors (ranges, TDoA, ultrasonic) in `factors`, contiguous
  /// after the IMU factor.
  std::size_t range_factors = 0;
};

/// Stream-only settings (the graph itself is configured by RangeImuGraphParams).
struct RangeImuStreamOptions {
  static constexpr std::int64_t kWaitForever = std::numeric_limits<std::int64_t>::max();
  /// How far IMU time may run past the newest state without a range before an
  /// IMU-only state is committed (see the file comment); >= max_state_interval_ns.
  std::int64_t max_range_wait_ns = 2'000'000'000;
  std::size_t initial_imu_capacity = 1024;  ///< IMU ring preallocation (samples)
  /// A measurement this far (ns) past the newest state, or an IMU sample
  /// this far past max_range_wait_ns after it, is refused
  /// (std::invalid_argument naming the gap) instead of planning a state
  /// every max_state_interval_ns across it: one stamp years ahead planned
  /// billions (issue 37). Ten minutes: longer than any initialization window
  /// or ranging gap the batch builder is given. The Localizer screens such
  /// rows first (input_screen.h) and re-initializes on an IMU gap; this
  /// bounds the stream on its own (at most 1200 planned states).
  std::int64_t max_gap_ns = 600'000'000'000;
  /// Per-link sigmas of new measurement factors (measurement_noise.h): off,
  /// every factor has its kind's sigma from RangeImuGraphParams. On, a link's
  /// factors get its DynamicCovariance estimate, fed from the innovation at
  /// the IMU prediction and the residual at the smoother's estimate right
  /// after the update (their product; see measurement_noise.h). The robust
  /// losses keep their shape in sigmas (the default asymmetric NLOS scale,
  /// 1.35 sigma, scales with the link). Here rather than in
  /// RangeImuGraphParams: it is how the stream builds factors over time, not
  /// what the graph is; LocalizerParams::stream carries it.
  DynamicCovarianceOptions dynamic_covariance;
  /// Where HeightBand::hold_sigma_m holds each state: learnt from the
  /// post-fit heights where ranges told the height (tracking: the Localizer
  /// sets it from HeightBand::learn_carry_height), or the band's middle
  /// (false: the initializer's batch, whose states are dead-reckoned while it
  /// is built).
  bool learn_carry_height = false;
  /// Each two-way range weighed by one over its anchor's ranges within the
  /// error's correlation time (range_repeats.h). Off here (the initializer's
  /// batch: its gates are costs per range); the Localizer's tracking takes
  /// LocalizerParams::range_repeats.
  RangeRepeatsParams range_repeats;
};

class RangeImuGraphStream {
 public:
  /// `p_w_anchors[id]` is the surveyed position of anchor id (m, world).
  /// Throws std::invalid_argument naming a bad parameter.
  RangeImuGraphStream(std::vector<Vec3> p_w_anchors, RangeImuGraphParams params,
                      RangeImuStreamOptions options = RangeImuStreamOptions());

  /// Opens state 0 at t0_ns and returns its increment: the priors on X0, V0, B0
  /// around the guess (zero bias) and those values. The priors' covariances
  /// are `covariance`'s blocks when given (the initializer's batch
  /// marginals, start_covariance.h), else RangeImuGraphParams::first_*.
  /// Samples added before are kept from t0 on (ranges before t0 are dropped,
  /// see droppedRanges()). Throws std::logic_error if already started,
  /// std::invalid_argument on a non-finite guess or a covariance block that
  /// is not positive definite.
  GraphIncrement start(std::int64_t t0_ns, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess,
                       const ImuBias& bias0_guess = ImuBias(),
                       const std::optional<StartCovariance>& covariance = std::nullopt);

  /// Throws std::invalid_argument if t_ns does not increase or a value is not
  /// finite; std::logic_error after finish().
  void addImu(const ImuSample& sample);
  /// Throws std::invalid_argument on an unknown anchor id, a non-finite range,
  /// a time before the previous measurement (of any kind), or a time before
  /// the newest state (before t0, or before a committed IMU-only state);
  /// std::logic_error after finish().
  void addRange(const RangeSample& sample) { addMeasurement(Measurement::of(sample)); }
  /// TDoA between two UWB anchors; as addRange, and the anchors must differ.
  void addTdoa(const TdoaSample& sample) { addMeasurement(Measurement::of(sample)); }
  /// Range to an ultrasonic beacon of RangeImuGraphParams::p_w_ultrasonic; as addRange.
  void addUltrasonic(const UltrasonicSample& sample) { addMeasurement(Measurement::of(sample)); }
  /// Any of the above: ranges, TDoA and ultrasonic ranges share the states
  /// (same_state_window_ns groups them) and one time order.
  void addMeasurement(const Measurement& m);
  /// No more samples: closes the open ranging group so its state can be emitted.
  /// Throws std::logic_error before start().
  void finish();

  /// The next increment, or nullopt when none is ready. `previous` is the
  /// smoother's estimate of the last emitted state: the new state's IMU factor is
  /// preintegrated with bias_hat = previous.bias, and its initial values are the
  /// IMU prediction from `previous` (bias: Phi * previous.bias). Throws
  /// std::logic_error before start(), std::invalid_argument if `previous` is
  /// not the last emitted state (index and t_ns) or not finite. If building the
  /// increment throws (e.g. std::domain_error: the window rotated too far), the
  /// stream is unchanged.
  std::optional<GraphIncrement> next(const StateEstimate& previous);

  bool started() const { return started_; }
  std::uint64_t lastStateIndex() const { return last_index_; }  ///< last emitted state
  std::int64_t lastStateTime() const { return last_t_ns_; }     ///< ns
  std::size_t imuBufferSize() const { return imu_.size(); }      ///< buffered IMU samples
  std::size_t imuBufferCapacity() const { return imu_.capacity(); }
  std::size_t pendingRanges() const { return ranges_.size(); }   ///< measurements not yet emitted
  std::size_t pendingStates() const { return plan_.size(); }     ///< planned states not yet emitted
  std::size_t droppedRanges() const { return dropped_ranges_; }  ///< measurements before t0, dropped by start()
  /// States emitted with a zero-velocity prior (RangeImuGraphParams::zero_velocity_sigma_m_s).
  std::size_t standstillStates() const { return standstill_states_; }
  /// Where new states' heights are held (tag height, m, world; HeightBand::hold_sigma_m).
  double carryHeightM() const { return carry_height_.heightM(); }
  const RangeImuGraphParams& params() const { return params_; }
  /// The sigmas given to measurement factors (and the dynamic estimate, if on).
  const MeasurementNoise& measurementNoise() const { return noise_; }
  RangeModel& rangeModel() { return range_model_; }

 private:
  struct PlannedState {
    std::int64_t t_ns = 0;
    std::size_t n_ranges = 0;  ///< its ranges, in ranges_ after the earlier states' ones
  };

  void planRange(const Measurement& m);
  void commitImuOnlyStates();
  bool stateReady(const PlannedState& s) const;
  bool carryClosed() const;
  GraphIncrement emitState(const StateEstimate& previous);
  GraphIncrement emitCarriedRanges();
  /// Adds state i's height band and vertical speed priors (when enabled);
  /// state i is interval_ns after the previous one.
  void addMotionPriors(std::uint64_t i, std::int64_t interval_ns, GraphIncrement& inc) const;
  /// Adds state i's zero-velocity prior if the IMU was still over (t_prev_ns,
  /// t_ns] and the previous state's estimate v_w_prev is slow (StandstillDetector::stillFor); true if it did.
  bool addStandstillPrior(std::uint64_t i, std::int64_t t_prev_ns, std::int64_t t_ns, const Vec3& v_w_prev,
                          GraphIncrement& inc) const;
  /// Adds the factors of ranges_[first, first + n) on state key x, noting anchors new to the graph.
  /// Factors of ranges_[first, first + n) on state `state` at state_t_ns.
  void addRangeFactors(std::size_t first, std::size_t n, std::uint64_t state, std::int64_t state_t_ns,
                       GraphIncrement& inc) const;
  /// The hold of state i's height towards the carry height (HeightBand::hold_sigma_m).
  void addCarryHold(std::uint64_t i, std::int64_t interval_ns, GraphIncrement& inc) const;
  /// State i's range m tells the carry height what it says about the height.
  void noteHeightEvidence(std::uint64_t i, const Measurement& m);
  /// The vertical weight of two-way range m (HeightBand::range_lever: 0
  /// below s0 = the range sigma over the band's half-width, 1 from 2 s0,
  /// smooth between; one sigma of excess the model does not remove fakes
  /// more height than the band's half-width below s0) and, in *sine, its
  /// vertical lever (the sine of the anchor's elevation seen from the band's
  /// middle); 1 without the lever.
  double verticalWeightOf(const Measurement& m, double* sine) const;
  /// The anchor key of a UWB anchor (adding its value if new to the graph).
  Key uwbAnchorKey(std::uint32_t id, GraphIncrement& inc) const;
  void addAnchorPriors(GraphIncrement& inc) const;
  void commitAnchors(const GraphIncrement& inc);

  std::vector<Vec3> p_w_anchors_;
  RangeImuGraphParams params_;
  RangeImuStreamOptions options_;
  RangeModel range_model_;  ///< two-way ranges: the configured loss, or the NLOS component when flagged
  TdoaModel tdoa_model_;  ///< TDoA: the configured loss, oriented NLOS tail or widened when flagged
  RobustLossPtr ultrasonic_loss_;
  PreintegratedImu pim_;  ///< scratch, reset per state
  MeasurementNoise noise_;
  CarryHeight carry_height_;  ///< where each state's height is held (HeightBand::hold_sigma_m)
  RangeRepeats range_repeats_;  ///< how many of an anchor's ranges share one error (options_.range_repeats)

  bool started_ = false;
  bool finished_ = false;
  std::vector<bool> anchor_in_graph_;  ///< anchor key and prior already emitted

  StandstillDetector standstill_;  ///< IMU back to one window before the last emitted state
  detail::GrowingRing<ImuSample> imu_;      ///< front: the sample in effect at the last emitted state
  detail::GrowingRing<Measurement> ranges_; ///< [carried measurements][plan_[0]'s][plan_[1]'s]...
  detail::GrowingRing<PlannedState> plan_;  ///< decided states not yet emitted, in time order
  std::size_t carry_ranges_ = 0;  ///< ranges at the front of ranges_ on the last emitted state

  std::uint64_t last_index_ = 0;       ///< last emitted state
  std::int64_t last_t_ns_ = 0;
  std::int64_t newest_state_t_ns_ = 0; ///< newest decided state (emitted or planned): ranges group on it
  bool have_imu_ = false, have_range_ = false;
  std::int64_t newest_imu_t_ns_ = 0, newest_range_t_ns_ = 0;
  std::size_t dropped_ranges_ = 0;
  std::size_t standstill_states_ = 0;
};

}  // namespace rilo
