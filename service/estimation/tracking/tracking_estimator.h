#pragma once
// What the Localizer tracks with after initialization: samples in (time
// order per stream), the newest state out. Two families implement it: the
// factor-graph estimator (RangeImuEstimator: the graph stream and a smoother)
// and the error-state EKF baseline (EkfEstimator). Single-threaded.
#include <cstdint>
#include <optional>
#include <vector>

#include "estimation/assembly/start_covariance.h"
#include "estimation/graph/values.h"
#include "estimation/measurements/los_gap_calibration.h"
#include "estimation/measurements/measurement.h"
#include "estimation/smoother/smoother.h"
#include "math/imu_bias.h"
#include "math/pose3.h"

namespace rilo {

struct StateEstimate;  // range_imu_graph_stream.h

/// A pose of the final (smoothed or filtered) trajectory.
struct TimedPose {
  std::int64_t t_ns = 0;
  Pose3 T_w_b;
};

class TrackingEstimator {
 public:
  virtual ~TrackingEstimator() = default;

  /// Starts at t0_ns around the given state. With `covariance` (the
  /// initializer's batch marginals, conditioned: start_covariance.h) the
  /// first-state priors (graph) or initial covariance (EKF) are that;
  /// without, the graph parameters' first-state priors (a loose guess).
  /// Throws std::invalid_argument if a covariance block is not positive definite.
  virtual UpdateStats start(std::int64_t t0_ns, const Pose3& T_w_b0, const Vec3& v_w0, const ImuBias& bias0,
                            const std::optional<StartCovariance>& covariance) = 0;
  UpdateStats start(std::int64_t t0_ns, const Pose3& T_w_b0, const Vec3& v_w0, const ImuBias& bias0) {
    return start(t0_ns, T_w_b0, v_w0, bias0, std::nullopt);
  }
  virtual bool started() const = 0;
  /// Expected excess of ranges the receiver flags as NLOS (m; range_model.h); no-op by default.
  virtual void setFlaggedExcess(double /*excess_m*/) {}
  /// The two-way ranges' NLOS flag threshold (dB; RangeModel::setNlosGapDb).
  virtual void setNlosGapDb(double /*gap_db*/) {}
  /// The two-way ranges' excess per power-gap bin (RangeModel::setGapExcess).
  virtual void setGapExcess(const GapExcessTable& /*table*/) {}
  virtual void addImu(const ImuSample& sample) = 0;
  /// A range, TDoA or ultrasonic range (Measurement::of(sample)).
  virtual void addMeasurement(const Measurement& m) = 0;
  void addRange(const RangeSample& sample) { addMeasurement(Measurement::of(sample)); }
  void addTdoa(const TdoaSample& sample) { addMeasurement(Measurement::of(sample)); }
  void addUltrasonic(const UltrasonicSample& sample) { addMeasurement(Measurement::of(sample)); }
  /// No more samples: lets the last measurements through.
  virtual void finish() = 0;
  /// Does the work that is ready; one UpdateStats per estimator update appended
  /// to `stats` when given. Returns the number of updates.
  virtual int process(std::vector<UpdateStats>* stats = nullptr) = 0;
  /// Newest estimate (valid after start()).
  virtual const StateEstimate& latest() const = 0;
  /// Appends the final poses of states that left the estimator (in time
  /// order); with `all`, also those still held (at the end of the data).
  virtual void drainSmoothed(std::vector<TimedPose>& out, bool all = false) = 0;
  /// Covariance of the newest pose, tangent [rot; trans] of Pose3, if available.
  virtual std::optional<CovarianceBlock> latestPoseCovariance() = 0;
  /// Covariance of the newest velocity (world, m^2/s^2), if available.
  virtual std::optional<CovarianceBlock> latestVelocityCovariance() = 0;
  /// States (EKF: groups) given the zero-velocity prior at a standstill since
  /// start (RangeImuGraphParams::zero_velocity_sigma_m_s).
  virtual std::uint64_t standstillPriors() const = 0;
};

}  // namespace rilo
