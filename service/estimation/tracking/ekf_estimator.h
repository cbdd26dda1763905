#pragma once
// The error-state EKF (estimation/ekf) as a TrackingEstimator: the filtering
// baseline the smoothers are compared against (the IMU-Ultrasonic-UWB paper's EKF column), on the
// same samples, initializer and outputs (`rilo replay --smoother ekf`).
//
// Timing: measurements wait until an IMU sample at or after their time has
// arrived; the filter then propagates to the measurement's exact time (an
// IMU sample interpolated between the two around it) and updates. Updates are
// grouped like the graph's states (RangeImuGraphParams::same_state_window_ns):
// a group ends when a measurement or the IMU passes its first time plus the
// window, and counts as one update whose state (at the group's last
// measurement) is latest(). The filtered states at those times are the
// "smoothed" trajectory (a filter does not smooth).
//
// TDoA rows of a group are one joint update (EkfParams::tdoa_group_update,
// ErrorStateEkf::updateTdoaGroup: group gate, correlated rows, iterated
// re-weighting) when the group closes, at the filter's time then (the last
// IMU sample before the one that passes the window: the rows' motion within
// the window, up to 25 ms of walking, is not modelled; the graph predicts
// each row at its own time since session 41, the EKF baseline not yet);
// ranges and ultrasonic ranges update as they come.
//
// Measurement models, noise, losses and the tag height band are the graph's (RangeImuGraphParams):
// ranges with range_loss and range_noise.sigma_m, TDoA with tdoa_loss and
// tdoa_sigma_m, ultrasonic with ultrasonic_loss and ultrasonic_sigma_m;
// anchors are the surveyed constants. The first covariance is the graph's
// first-state priors. With EkfParams::dynamic_covariance on, each update's
// sigma is its link's DynamicCovariance estimate instead (nominal: the
// graph's sigma of its kind), fed with the update's innovation and H P H^T,
// gated updates included (clipping bounds their pull; a link gated for good
// must still be able to earn a larger sigma). `rilo replay` turns it on for
// TDoA recordings like for the graph estimators: with the nominal 0.15 m
// against the office sim's 1.3-1.5 m NLOS TDoA errors the filter's
// covariance collapsed and it diverged. Per-sample work is fixed size; buffers grow to their
// working size once (pending measurements, drained poses).
#include <memory>
#include <vector>

#include "estimation/assembly/measurement_noise.h"
#include "estimation/assembly/range_imu_graph.h"
#include "estimation/assembly/range_imu_graph_stream.h"  // StateEstimate
#include "estimation/ekf/error_state_ekf.h"
#include "estimation/measurements/standstill.h"
#include "estimation/tracking/tracking_estimator.h"

namespace rilo {

class EkfEstimator final : public TrackingEstimator {
 public:
  /// Throws std::invalid_argument on bad parameters (naming the field).
  EkfEstimator(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph, const EkfParams& ekf = EkfParams());

  using TrackingEstimator::start;
  /// The initial covariance: `covariance` in the filter's error chart (rotation
  /// body, position world: the pose block's translation rotated by R), else
  /// the graph's first-state priors.
  UpdateStats start(std::int64_t t0_ns, const Pose3& T_w_b0, const Vec3& v_w0, const ImuBias& bias0,
                    const std::optional<StartCovariance>& covariance) override;
  bool started() const override { return ekf_.initialized(); }
  void setFlaggedExcess(double excess_m) override { range_model_.setFlaggedExcess(excess_m); }
  void setNlosGapDb(double gap_db) override { range_model_.setNlosGapDb(gap_db); }
  void setGapExcess(const GapExcessTable& table) override { range_model_.setGapExcess(table); }
  void addImu(const ImuSample& sample) override;
  void addMeasurement(const Measurement& m) override;
  void finish() override;
  int process(std::vector<UpdateStats>* stats = nullptr) override;
  const StateEstimate& latest() const override { return latest_; }
  void drainSmoothed(std::vector<TimedPose>& out, bool all = false) override;
  std::optional<CovarianceBlock> latestPoseCovariance() override;
  std::optional<CovarianceBlock> latestVelocityCovariance() override;
  std::uint64_t standstillPriors() const override { return ekf_.counters().zero_velocity.accepted; }

  const ErrorStateEkf& filter() const { return ekf_; }
  const MeasurementNoise& measurementNoise() const { return noise_; }

 private:
  /// Propagates to t_ns with an IMU sample interpolated between the last one and `next`.
  void propagateTo(std::int64_t t_ns, const ImuSample& next);
  void apply(const Measurement& m);
  void openGroup(std::int64_t t_ns);
  void closeGroup();
  /// Applies the buffered TDoA rows of the open group as one update (EkfParams::tdoa_group_update).
  void flushTdoaGroup();
  /// After any update: the tag height band (graph_.height_band), when on.
  void applyHeightBand();
  /// The graph's standstill prior for a group opening at t_ns (openGroup).
  void applyStandstill(std::int64_t t_ns);
  /// Applies the pending measurements up to t_ns (all with `all`), IMU `next` bounding them.
  void drainPending(const ImuSample* next, bool all);

  std::vector<Vec3> p_w_anchors_;
  RangeImuGraphParams graph_;
  ErrorStateEkf ekf_;
  RangeModel range_model_;  ///< two-way ranges (range_model.h)
  TdoaModel tdoa_model_;  ///< TDoA rows: the configured symmetric loss, the sigma widened when flagged
  RobustLossPtr ultrasonic_loss_;
  MeasurementNoise noise_;

  bool have_imu_ = false;
  ImuSample last_imu_;
  std::vector<Measurement> pending_;  // time order, not yet applied
  StandstillDetector standstill_;     // IMU back to one window before the last group
  std::size_t pending_head_ = 0;

  // The open update group.
  bool group_open_ = false;
  std::int64_t group_t0_ns_ = 0;
  std::int64_t last_group_t0_ns_ = 0;  ///< the previous group's (or the start's) time
  std::uint64_t groups_opened_ = 0;   ///< since start(): the first gets a whole correlation time's vertical prior
  int group_size_ = 0, group_accepted_ = 0;
  double group_time_s_ = 0.0;
  StateEstimate group_state_;
  // TDoA rows of the open group awaiting their joint update at its close.
  EkfTdoaRow tdoa_rows_[kEkfMaxGroupRows];
  Measurement tdoa_meas_[kEkfMaxGroupRows];
  int tdoa_n_ = 0;

  StateEstimate latest_;
  std::uint64_t updates_ = 0;
  std::vector<UpdateStats> ready_;  // closed groups not yet reported by process()
  std::vector<TimedPose> filtered_;  // not yet drained
};

}  // namespace rilo
