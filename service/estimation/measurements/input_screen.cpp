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
  if (!(max_imu_jump_s > 0.0 && max_imu_jump_s <= 3600.0)) fail("max_imu_jump_s", "must be in (0, 3600] s");
  if (jump_confirmations < 0) fail("jump_confirmations", "must be >= 0");
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

StampJumpGuard::Verdict StampJumpGuard::judge(std::int64_t newest_ns, std::int64_t t_ns, std::int64_t max_jump_ns,
                                              int confirmations) noexcept {
  if (t_ns - newest_ns <= max_jump_ns) {
    seen_ = 0;  // the old timeline goes on: a pending candidate was a bad stamp
    return Verdict::kTake;
  }
  // Ahead of the stream: the first sample of a new timeline, or the next one
  // continuing a pending candidate.
  // A confirmation must be a sample of its own, not a stamp nudged past the
  // candidate (a driver forcing increasing times writes last + 1 ns).
  const bool continues =
      seen_ > 0 && t_ns - candidate_ns_ >= kMinConfirmationStepNs && t_ns - candidate_ns_ <= max_jump_ns;
  if (seen_ > 0 && !continues && t_ns > candidate_ns_ && t_ns - candidate_ns_ < kMinConfirmationStepNs) {
    return Verdict::kHold;  // too close to the candidate to confirm it, and still far ahead
  }
  seen_ = continues ? seen_ + 1 : 1;
  candidate_ns_ = t_ns;
  if (seen_ <= confirmations) return Verdict::kHold;
  seen_ = 0;
  return Verdict::kTakeJump;
}

InputScreen::InputScreen(InputScreenParams params) : params_(params) {
  params_.validate();
  max_jump_ns_ = static_cast<std::int64_t>(std::llround(params_.max_time_jump_s * 1e9));
  max_imu_jump_ns_ = static_cast<std::int64_t>(std::llround(params_.max_imu_jump_s * 1e9));
}

bool InputScreen::drop(InputDrop reason) {
  ++counts_.by_reason[static_cast<int>(reason)];
  return false;
}

namespace {

bool rangeInBounds(double value_m, const InputScreenParams& p) { return value_m > 0.0 && value_m <= p.max_range_m; }

}  // namespace

InputDrop InputScreen::judgeValue(const ImuSample& s, const InputScreenParams& p) noexcept {
  if (!s.accel_m_s2.allFinite() || !s.gyro_rad_s.allFinite()) return InputDrop::kNotFinite;
  if (s.accel_m_s2.cwiseAbs().maxCoeff() > p.max_accel_m_s2 || s.gyro_rad_s.cwiseAbs().maxCoeff() > p.max_gyro_rad_s) {
    return InputDrop::kBeyondFullScale;
  }
  return InputDrop::kCount;
}

InputDrop InputScreen::judgeValue(const RangeSample& s, const InputScreenParams& p) noexcept {
  if (!std::isfinite(s.range_m)) return InputDrop::kNotFinite;
  return rangeInBounds(s.range_m, p) ? InputDrop::kCount : InputDrop::kOutOfBounds;
}

InputDrop InputScreen::judgeValue(const TdoaSample& s, const InputScreenParams& p) noexcept {
  if (!std::isfinite(s.diff_m)) return InputDrop::kNotFinite;
  return std::abs(s.diff_m) <= p.max_range_m ? InputDrop::kCount : InputDrop::kOutOfBounds;
}

InputDrop InputScreen::judgeValue(const UltrasonicSample& s, const InputScreenParams& p) noexcept {
  if (!std::isfinite(s.range_m)) return InputDrop::kNotFinite;
  return rangeInBounds(s.range_m, p) ? InputDrop::kCount : InputDrop::kOutOfBounds;
}

bool InputScreen::admit(const ImuSample& s) {
  if (const InputDrop why = judgeValue(s, params_); why != InputDrop::kCount) return drop(why);
  if (imu_.seen && s.t_ns <= imu_.newest_ns) {
    imu_.jump.cancel();
    return drop(InputDrop::kNonMonotonic);
  }
  if (imu_.seen) {
    switch (imu_.jump.judge(imu_.newest_ns, s.t_ns, max_imu_jump_ns_, params_.jump_confirmations)) {
      case StampJumpGuard::Verdict::kHold: return drop(InputDrop::kFarFuture);
      case StampJumpGuard::Verdict::kTakeJump: ++counts_.time_jumps; break;  // the IMU clock moved on (a paused device)
      case StampJumpGuard::Verdict::kTake: break;
    }
  }
  imu_.seen = true;
  imu_.newest_ns = s.t_ns;
  return true;
}

bool InputScreen::admitStamp(Stream& stream, std::int64_t t_ns) {
  if (stream.seen && t_ns < stream.newest_ns) {
    stream.jump.cancel();
    return drop(InputDrop::kNonMonotonic);
  }
  if (imu_.seen) {
    // Ahead of the IMU that drives the estimator: the IMU confirms its own jumps.
    if (t_ns - imu_.newest_ns > max_jump_ns_) return drop(InputDrop::kFarFuture);
  } else if (stream.seen &&
             stream.jump.judge(stream.newest_ns, t_ns, max_jump_ns_, params_.jump_confirmations) ==
                 StampJumpGuard::Verdict::kHold) {
    return drop(InputDrop::kFarFuture);  // before any IMU: ahead of its own stream
  }
  stream.seen = true;
  stream.newest_ns = t_ns;
  return true;
}

bool InputScreen::admit(const RangeSample& s) {
  if (const InputDrop why = judgeValue(s, params_); why != InputDrop::kCount) return drop(why);
  return admitStamp(range_, s.t_ns);
}

bool InputScreen::admit(const TdoaSample& s) {
  if (const InputDrop why = judgeValue(s, params_); why != InputDrop::kCount) return drop(why);
  return admitStamp(tdoa_, s.t_ns);
}

bool InputScreen::admit(const UltrasonicSample& s) {
  if (const InputDrop why = judgeValue(s, params_); why != InputDrop::kCount) return drop(why);
  return admitStamp(ultrasonic_, s.t_ns);
}

}  // namespace rilo
