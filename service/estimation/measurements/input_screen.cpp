#include "estimation/measurements/input_screen.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

void InputScreenParams::validate() const {
  auto fail = [](const char* field, const char* why) {
    throw std::invalid_argument(std::string("InputScreenParams.") + field + ": " + why);
  };
  if (!(std::isfinite(max_range_m) && max_range_m > 0.0)) fail("max_range_m", "must be finite and > 0");
  if (!(max_accel_m_s2 > 0.0)) fail("max_accel_m_s2", "must be > 0");
  if (!(max_gyro_rad_s > 0.0)) fail("max_gyro_rad_s", "must be > 0");
  if (!(max_time_jump_s > 0.0 && max_time_jump_s <= 3600.0)) fail("max_time_jump_s", "must be in (0, 3600] s");
  if (jump_confirmations < 1) fail("jump_confirmations", "must be >= 1");
}

std::string_view inputDropName(InputDrop reason) {
  switch (reason) {
    case InputDrop::kNotFinite: return "not_finite";
    case InputDrop::kOutOfBounds: return "out_of_bounds";
    case InputDrop::kBeyondFullScale: return "beyond_full_scale";
    case InputDrop::kNonMonotonic: return "non_monotonic";
    case InputDrop::kFarFuture: return "far_future";
    case InputDrop::kCount: break;
  }
  return "unknown";
}

std::uint64_t InputDropCounts::total() const {
  std::uint64_t n = 0;
  for (std::uint64_t c : by_reason) n += c;
  return n;
}

InputScreen::InputScreen(InputScreenParams params) : params_(params) {
  params_.validate();
  max_jump_ns_ = static_cast<std::int64_t>(std::llround(params_.max_time_jump_s * 1e9));
}

bool InputScreen::drop(InputDrop reason) {
  ++counts_.by_reason[static_cast<int>(reason)];
  return false;
}

bool InputScreen::inBounds(double value_m) const {
  return value_m > 0.0 && value_m <= params_.max_range_m;
}

bool InputScreen::admit(const ImuSample& s) {
  if (!s.accel_m_s2.allFinite() || !s.gyro_rad_s.allFinite()) return drop(InputDrop::kNotFinite);
  if (s.accel_m_s2.cwiseAbs().maxCoeff() > params_.max_accel_m_s2 ||
      s.gyro_rad_s.cwiseAbs().maxCoeff() > params_.max_gyro_rad_s) {
    return drop(InputDrop::kBeyondFullScale);
  }
  if (imu_.seen && s.t_ns <= imu_.newest_ns) {
    jump_seen_ = 0;  // the old timeline goes on: a pending jump was a bad stamp
    return drop(InputDrop::kNonMonotonic);
  }
  if (imu_.seen && s.t_ns - imu_.newest_ns > max_jump_ns_) {
    // Ahead of the stream: the first sample of a new timeline, or the next
    // one continuing a pending jump.
    const bool continues = jump_seen_ > 0 && s.t_ns > jump_newest_ns_ && s.t_ns - jump_newest_ns_ <= max_jump_ns_;
    jump_seen_ = continues ? jump_seen_ + 1 : 1;
    jump_newest_ns_ = s.t_ns;
    if (jump_seen_ <= params_.jump_confirmations) return drop(InputDrop::kFarFuture);
    ++counts_.time_jumps;  // confirmed: the IMU clock moved on (or the device paused)
  }
  jump_seen_ = 0;
  imu_.seen = true;
  imu_.newest_ns = s.t_ns;
  return true;
}

bool InputScreen::admitStamp(Stream& stream, std::int64_t t_ns) {
  if (stream.seen && t_ns < stream.newest_ns) return drop(InputDrop::kNonMonotonic);
  // Ahead of the IMU that drives the estimator (or, before any IMU, of its own stream).
  const Stream& reference = imu_.seen ? imu_ : stream;
  if (reference.seen && t_ns - reference.newest_ns > max_jump_ns_) return drop(InputDrop::kFarFuture);
  stream.seen = true;
  stream.newest_ns = t_ns;
  return true;
}

bool InputScreen::admit(const RangeSample& s) {
  if (!std::isfinite(s.range_m)) return drop(InputDrop::kNotFinite);
  if (!inBounds(s.range_m)) return drop(InputDrop::kOutOfBounds);
  return admitStamp(range_, s.t_ns);
}

bool InputScreen::admit(const TdoaSample& s) {
  if (!std::isfinite(s.diff_m)) return drop(InputDrop::kNotFinite);
  if (std::abs(s.diff_m) > params_.max_range_m) return drop(InputDrop::kOutOfBounds);
  return admitStamp(tdoa_, s.t_ns);
}

bool InputScreen::admit(const UltrasonicSample& s) {
  if (!std::isfinite(s.range_m)) return drop(InputDrop::kNotFinite);
  if (!inBounds(s.range_m)) return drop(InputDrop::kOutOfBounds);
  return admitStamp(ultrasonic_, s.t_ns);
}

}  // namespace rilo
