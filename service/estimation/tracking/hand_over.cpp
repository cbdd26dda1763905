#include "estimation/tracking/hand_over.h"

#include <stdexcept>
#include <vector>

#include "estimation/init/window_time.h"

namespace rilo {

using init_detail::imuIndexAt;
using init_detail::rangeIndexFrom;

int handOver(const Initializer& initializer, TrackingEstimator& estimator) {
  if (!initializer.initialized()) {
    throw std::logic_error("handOver: the initializer is not initialized (" + initializer.status().message + ")");
  }
  if (estimator.started()) throw std::logic_error("handOver: the estimator was already started");
  const StateEstimate& s = initializer.result().state;
  int updates = 0;
  // The batch's bias and marginals too: the hand-over loses nothing but the cross-covariances.
  estimator.start(s.t_ns, s.T_w_b, s.v_w, s.bias, initializer.result().start_covariance);
  const std::vector<ImuSample>& imu = initializer.imuBuffer();
  const std::vector<Measurement>& meas = initializer.measurementBuffer();
  std::size_t i = imuIndexAt(imu, s.t_ns), r = rangeIndexFrom(meas, s.t_ns);
  while (i < imu.size() || r < meas.size()) {
    if (r < meas.size() && (i >= imu.size() || meas[r].t_ns <= imu[i].t_ns)) {
      estimator.addMeasurement(meas[r++]);
    } else {
      estimator.addImu(imu[i++]);
    }
    updates += estimator.process();
  }
  return updates;
}

}  // namespace rilo
