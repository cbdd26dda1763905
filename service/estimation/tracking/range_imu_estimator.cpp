#include "estimation/tracking/range_imu_estimator.h"

#include <stdexcept>

namespace rilo {

RangeImuEstimator::RangeImuEstimator(std::vector<Vec3> p_w_anchors, const RangeImuGraphParams& graph_params,
                                     std::unique_ptr<Smoother> smoother, RangeImuStreamOptions stream_options)
    : stream_(std::move(p_w_anchors), graph_params, stream_options), smoother_(std::move(smoother)) {
  if (!smoother_) throw std::invalid_argument("RangeImuEstimator: null smoother");
}

UpdateStats RangeImuEstimator::start(std::int64_t t0_ns, const Pose3& T_w_b0_guess, const Vec3& v_w0_guess,
                                     const ImuBias& bias0_guess, const std::optional<StartCovariance>& covariance) {
  return absorb(stream_.start(t0_ns, T_w_b0_guess, v_w0_guess, bias0_guess, covariance));
}

int RangeImuEstimator::process(std::vector<UpdateStats>* stats) {
  int updates = 0;
  while (auto increment = stream_.next(latest_)) {
    const UpdateStats s = absorb(*increment);
    if (stats) stats->push_back(s);
    ++updates;
  }
  return updates;
}

UpdateStats RangeImuEstimator::absorb(const GraphIncrement& increment) {
  timestamps_.clear();
  for (const auto& [key, t_ns] : increment.key_times_ns) {
    timestamps_[key] = t_ns;
    if (keySymbol(key) == 'x') state_times_[keyIndex(key)] = t_ns;
  }
  const UpdateStats stats = smoother_->update(increment.factors, increment.values, timestamps_);
  const std::uint64_t i = stream_.lastStateIndex();
  latest_.index = i;
  latest_.t_ns = stream_.lastStateTime();
  latest_.T_w_b = std::get<Pose3>(smoother_->estimate(sym::X(i)));
  latest_.v_w = std::get<Vec3>(smoother_->estimate(sym::V(i)));
  latest_.bias = std::get<ImuBias>(smoother_->estimate(sym::B(i)));
  return stats;
}

void RangeImuEstimator::drainSmoothed(std::vector<TimedPose>& out, bool all) {
  drained_.clear();
  smoother_->drainMarginalized(drained_);
  for (const auto& [key, value] : drained_) {
    if (keySymbol(key) != 'x') continue;
    const auto it = state_times_.find(keyIndex(key));
    if (it == state_times_.end()) continue;
    out.push_back({it->second, std::get<Pose3>(value)});
    state_times_.erase(it);
  }
  if (all) {
    for (const auto& [index, t_ns] : state_times_) {
      if (smoother_->exists(sym::X(index))) out.push_back({t_ns, std::get<Pose3>(smoother_->estimate(sym::X(index)))});
    }
    state_times_.clear();
  }
}

std::optional<CovarianceBlock> RangeImuEstimator::latestPoseCovariance() {
  return smoother_->marginalCovariance(sym::X(latest_.index));
}

std::optional<CovarianceBlock> RangeImuEstimator::latestVelocityCovariance() {
  return smoother_->marginalCovariance(sym::V(latest_.index));
}

}  // namespace rilo
