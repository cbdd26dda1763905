#include "rilod/sample_screen.h"

#include <cmath>
#include <variant>

namespace rilo {

SampleScreen::SampleScreen(const InputScreenParams& params)
    : params_(params),
      max_jump_ns_(static_cast<std::int64_t>(std::llround(params.max_time_jump_s * 1e9))),
      max_imu_jump_ns_(static_cast<std::int64_t>(std::llround(params.max_imu_jump_s * 1e9))) {
  params_.validate();
}

SampleVerdict SampleScreen::verdictOf(InputDrop why) noexcept {
  switch (why) {
    case InputDrop::kNotFinite: return SampleVerdict::kNonFinite;
    case InputDrop::kOutOfBounds: return SampleVerdict::kOutOfBounds;
    case InputDrop::kBeyondFullScale: return SampleVerdict::kBeyondFullScale;
    default: return SampleVerdict::kAccept;
  }
}

SampleVerdict SampleScreen::order(Last& last, std::int64_t t_ns, std::uint32_t a, std::uint32_t b, bool key_matters,
                                  std::int64_t max_jump_ns) noexcept {
  if (last.seen) {
    if (t_ns < last.t_ns) {
      last.jump.cancel();
      return SampleVerdict::kOutOfOrder;
    }
    if (t_ns == last.t_ns && (!key_matters || (a == last.a && b == last.b))) return SampleVerdict::kDuplicate;
    if (max_jump_ns >= 0 &&
        last.jump.judge(last.t_ns, t_ns, max_jump_ns, params_.jump_confirmations) == StampJumpGuard::Verdict::kHold) {
      return SampleVerdict::kFarFuture;
    }
  }
  last.seen = true;
  last.t_ns = t_ns;
  last.a = a;
  last.b = b;
  return SampleVerdict::kAccept;
}

SampleVerdict SampleScreen::measurement(Last& last, std::int64_t t_ns, std::uint32_t a, std::uint32_t b,
                                        std::int64_t newest_imu_ns) noexcept {
  if (newest_imu_ns == kNoImu) return order(last, t_ns, a, b, true, max_jump_ns_);
  if (t_ns - newest_imu_ns > max_jump_ns_) return SampleVerdict::kFarFuture;
  return order(last, t_ns, a, b, true, -1);
}

SampleVerdict SampleScreen::check(const Sample& sample, std::int64_t newest_imu_ns) noexcept {
  if (const auto* imu = std::get_if<ImuSample>(&sample)) {
    if (const SampleVerdict v = verdictOf(InputScreen::judgeValue(*imu, params_)); v != SampleVerdict::kAccept) return v;
    return order(imu_, imu->t_ns, 0, 0, false, max_imu_jump_ns_);
  }
  if (const auto* range = std::get_if<RangeSample>(&sample)) {
    if (const SampleVerdict v = verdictOf(InputScreen::judgeValue(*range, params_)); v != SampleVerdict::kAccept) return v;
    return measurement(range_, range->t_ns, range->anchor_id, range->tag_id, newest_imu_ns);
  }
  if (const auto* tdoa = std::get_if<TdoaSample>(&sample)) {
    if (const SampleVerdict v = verdictOf(InputScreen::judgeValue(*tdoa, params_)); v != SampleVerdict::kAccept) return v;
    return measurement(tdoa_, tdoa->t_ns, tdoa->anchor_a, tdoa->anchor_b, newest_imu_ns);
  }
  const auto* us = std::get_if<UltrasonicSample>(&sample);
  if (us == nullptr) return SampleVerdict::kAccept;  // no other alternative exists
  if (const SampleVerdict v = verdictOf(InputScreen::judgeValue(*us, params_)); v != SampleVerdict::kAccept) return v;
  return measurement(ultrasonic_, us->t_ns, us->anchor_id, 0, newest_imu_ns);
}

}  // namespace rilo
