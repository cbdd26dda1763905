#pragma once
// UWB antennas on the body. A device may carry more than one (a drone or a
// cart with a tag at each end; a recording's tags.csv): each range then says
// which one measured it (RangeSample::tag_id), and is predicted from that
// antenna. A tag not in the table, and every range without one, uses the
// single antenna's lever arm (RangeImuGraphParams::p_b_tag). A handful of
// entries: found by a linear scan, no allocation.
#include <cstdint>
#include <vector>

#include "math/types.h"

namespace rilo {

struct TagLeverArm {
  std::uint32_t tag_id = 0;
  Vec3 p_b_m = Vec3::Zero();  ///< antenna in the body frame (m)
};

/// The lever arm of `tag_id` in `arms`, else `fallback`.
inline const Vec3& leverArmOf(const std::vector<TagLeverArm>& arms, std::uint32_t tag_id, const Vec3& fallback) {
  for (const TagLeverArm& a : arms) {
    if (a.tag_id == tag_id) return a.p_b_m;
  }
  return fallback;
}

/// Throws std::invalid_argument naming `where` for a non-finite arm or a repeated id.
void validateTagLeverArms(const std::vector<TagLeverArm>& arms, const char* where);

}  // namespace rilo
