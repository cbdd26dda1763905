#include "estimation/measurements/standstill.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

void StandstillParams::validate() const {
  auto fail = [](const char* field, const char* what) {
    throw std::invalid_argument(std::string("StandstillParams.") + field + " " + what);
  };
  if (!(window_s > 0.0 && std::isfinite(window_s))) fail("window_s", "must be positive and finite");
  if (!(accel_std_m_s2 >= 0.0 && std::isfinite(accel_std_m_s2))) fail("accel_std_m_s2", "must be finite and >= 0");
  if (!(gyro_rad_s >= 0.0)) fail("gyro_rad_s", "must be >= 0 (+inf: no turn test)");
  if (!(max_speed_m_s > 0.0)) fail("max_speed_m_s", "must be > 0 (+inf: no speed test)");
}

StandstillDetector::StandstillDetector(StandstillParams params, std::size_t initial_capacity)
    : params_(params), window_ns_(0), samples_(initial_capacity) {
  params_.validate();
  window_ns_ = static_cast<std::int64_t>(std::llround(params_.window_s * 1e9));
}

void StandstillDetector::add(const ImuSample& sample) { samples_.push_back(sample); }

bool StandstillDetector::stillOver(std::int64_t t_from_ns, std::int64_t t_to_ns) const {
  const std::int64_t t0 = std::min(t_from_ns, t_to_ns - window_ns_);
  Vec3 sum = Vec3::Zero(), sum2 = Vec3::Zero();
  double gyro = 0.0;
  std::size_t n = 0;
  std::int64_t first = 0;
  // Newest first: the window is at the ring's end.
  for (std::size_t k = samples_.size(); k-- > 0;) {
    const ImuSample& s = samples_[k];
    if (s.t_ns > t_to_ns) continue;
    if (s.t_ns < t0) break;
    sum += s.accel_m_s2;
    sum2 += s.accel_m_s2.cwiseAbs2();
    gyro += s.gyro_rad_s.norm();
    first = s.t_ns;
    ++n;
  }
  if (n < 3) return false;
  if (static_cast<double>(t_to_ns - first) < 0.9 * static_cast<double>(t_to_ns - t0)) return false;
  const double nd = static_cast<double>(n);
  const Vec3 var = (sum2 - sum.cwiseAbs2() / nd) / (nd - 1.0);
  return std::sqrt(std::max(0.0, var.maxCoeff())) <= params_.accel_std_m_s2 && gyro / nd <= params_.gyro_rad_s;
}

void StandstillDetector::dropBefore(std::int64_t t_ns) {
  const std::int64_t keep_from = t_ns - window_ns_;
  std::size_t n = 0;
  while (n < samples_.size() && samples_[n].t_ns < keep_from) ++n;
  samples_.pop_front(n);
}

}  // namespace rilo
