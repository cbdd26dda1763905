#include "rilod/sample_screen.h"

#include <cmath>
#include <variant>

namespace rilo {

SampleVerdict SampleScreen::order(Last& last, std::int64_t t_ns, std::uint32_t a, std::uint32_t b,
                                  bool key_matters) noexcept {
  if (last.seen) {
    if (t_ns < last.t_ns) return SampleVerdict::kOutOfOrder;
    if (t_ns == last.t_ns && (!key_matters || (a == last.a && b == last.b))) return SampleVerdict::kDuplicate;
  }
  last.seen = true;
  last.t_ns = t_ns;
  last.a = a;
  last.b = b;
  return SampleVerdict::kAccept;
}

SampleVerdict SampleScreen::check(const Sample& sample) noexcept {
  if (const auto* imu = std::get_if<ImuSample>(&sample)) {
    if (!imu->gyro_rad_s.allFinite() || !imu->accel_m_s2.allFinite()) return SampleVerdict::kNonFinite;
    return order(imu_, imu->t_ns, 0, 0, false);
  }
  if (const auto* range = std::get_if<RangeSample>(&sample)) {
    if (!std::isfinite(range->range_m)) return SampleVerdict::kNonFinite;
    return order(range_, range->t_ns, range->anchor_id, range->tag_id, true);
  }
  if (const auto* tdoa = std::get_if<TdoaSample>(&sample)) {
    if (!std::isfinite(tdoa->diff_m)) return SampleVerdict::kNonFinite;
    return order(tdoa_, tdoa->t_ns, tdoa->anchor_a, tdoa->anchor_b, true);
  }
  const auto* us = std::get_if<UltrasonicSample>(&sample);
  if (us == nullptr) return SampleVerdict::kAccept;  // no other alternative exists
  if (!std::isfinite(us->range_m)) return SampleVerdict::kNonFinite;
  return order(ultrasonic_, us->t_ns, us->anchor_id, 0, true);
}

}  // namespace rilo
