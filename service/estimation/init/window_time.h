#pragma once
// Time helpers the initializer's attempt (initializer.cpp), its batch solve
// (batch.cpp) and the hand-over (tracking/hand_over.cpp) share: seconds <->
// ns, and where a time falls in the buffered IMU samples and measurements.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "estimation/measurements/measurement.h"
#include "sensors/samples.h"

namespace rilo::init_detail {

inline std::int64_t toNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }
inline double toS(std::int64_t ns) { return 1e-9 * static_cast<double>(ns); }

/// Index of the IMU sample in effect at t (last one at or before t; 0 if none).
inline std::size_t imuIndexAt(const std::vector<ImuSample>& imu, std::int64_t t_ns) {
  auto it = std::upper_bound(imu.begin(), imu.end(), t_ns, [](std::int64_t t, const ImuSample& m) { return t < m.t_ns; });
  return it == imu.begin() ? 0 : static_cast<std::size_t>(it - imu.begin()) - 1;
}

/// First measurement at or after t.
inline std::size_t rangeIndexFrom(const std::vector<Measurement>& meas, std::int64_t t_ns) {
  auto it = std::lower_bound(meas.begin(), meas.end(), t_ns,
                             [](const Measurement& m, std::int64_t t) { return m.t_ns < t; });
  return static_cast<std::size_t>(it - meas.begin());
}

}  // namespace rilo::init_detail
