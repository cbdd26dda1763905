#pragma once
// The Ranging-IMU Fusion paper's estimator, online: samples in, smoothed newest state out. Owns a
// RangeImuGraphStream (which turns samples into graph increments) and a
// smoother (which absorbs them); after every increment the newest state's
// estimate seeds the next IMU prediction and preintegration.
// Single-threaded: the estimation thread owns it.
#include <map>
#include <memory>
#include <vector>

#include "estimation/assembly/range_imu_graph_stream.h"
#include "estimation/smoother/smoother.h"
#include "estimation/tracking/tracking_estimator.h"

namespace rilo {

class RangeImuEstimator final : public TrackingEstimator {
 public:
  /// Throws std::invalid_argument on bad parameters (see the stream) or a null smoother.
  RangeImuEstimator(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph_params,
                    std::unique_ptr<Smoother> smoother, RangeImuStreamOptions stream_options = {});

  using TrackingEstimator::start;
  /// Opens state 0 at t0_ns around the given guess and absorbs its priors
  /// (RangeImuGraphStream::start).
  UpdateStats start(std::int64_t t0_ns, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess, const ImuBias& bias0_guess,
                    const std::optional<StartCovariance>& covariance) override;
  UpdateStats start(std::int64_t t0_ns, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess) {
    return start(t0_ns, T_w_b0_guess, v_w0_guess, ImuBias());
  }
  bool started() const override { return stream_.started(); }
  void setFlaggedExcess(double excess_m) override { stream_.rangeModel().setFlaggedExcess(excess_m); }
  void setNlosGapDb(double gap_db) override { stream_.rangeModel().setNlosGapDb(gap_db); }
  void setGapExcess(const GapExcessTable& table) override { stream_.rangeModel().setGapExcess(table); }
  void addImu(const ImuSample& sample) override { stream_.addImu(sample); }
  void addMeasurement(const Measurement& m) override { stream_.addMeasurement(m); }
  /// No more samples: lets the last ranging group through.
  void finish() override { stream_.finish(); }

  /// Feeds every ready increment to the smoother; appends one UpdateStats per
  /// update to `stats` when given. Returns the number of updates.
  int process(std::vector<UpdateStats>* stats = nullptr) override;

  /// Smoothed estimate of the newest state (valid after start()).
  const StateEstimate& latest() const override { return latest_; }

  using TimedPose = rilo::TimedPose;
  /// Appends the final poses of the states that left the smoother's window
  /// since the last call (the smoothed trajectory), in time order; with
  /// `all`, also every state still in the window (at the end of the data).
  void drainSmoothed(std::vector<TimedPose>& out, bool all = false) override;
  /// Marginal covariances of the newest state from the smoother.
  std::optional<CovarianceBlock> latestPoseCovariance() override;
  std::optional<CovarianceBlock> latestVelocityCovariance() override;
  std::uint64_t standstillPriors() const override { return stream_.standstillStates(); }
  Smoother& smoother() { return *smoother_; }
  const Smoother& smoother() const { return *smoother_; }
  const RangeImuGraphStream& stream() const { return stream_; }

 private:
  UpdateStats absorb(const GraphIncrement& increment);

  RangeImuGraphStream stream_;
  std::unique_ptr<Smoother> smoother_;
  StateEstimate latest_;
  KeyTimestamps timestamps_;  // scratch
  std::map<std::uint64_t, std::int64_t> state_times_;  // states in the window: index -> t_ns
  std::vector<std::pair<Key, Variable>> drained_;      // scratch
};

}  // namespace rilo
