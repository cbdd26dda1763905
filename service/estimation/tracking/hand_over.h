#pragma once
// The start of tracking: an initialized Initializer hands its state, its
// covariance and its buffered samples to a TrackingEstimator.
#include "estimation/init/initializer.h"
#include "estimation/tracking/tracking_estimator.h"

namespace rilo {

/// Hands an initialized Initializer over to an estimator that was not
/// started: starts it at the result's state (time, pose, velocity, bias;
/// priors of the result's start_covariance when it has one) and
/// replays every buffered sample from that time on (IMU from the sample in
/// effect at it; measurements at or after it), in time order, then lets it
/// process. Afterwards feed new samples to the estimator. Returns the number
/// of smoother updates. Throws std::logic_error if the initializer is not
/// initialized or the estimator was already started.
int handOver(const Initializer& initializer, TrackingEstimator& estimator);

}  // namespace rilo
