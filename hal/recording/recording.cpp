#include "hal/recording/recording.h"

namespace rilo {

std::string_view toString(RangingKind kind) {
  switch (kind) {
    case RangingKind::kSsTwr: return "ss-twr";
    case RangingKind::kDsTwr: return "ds-twr";
    case RangingKind::kTdoa: return "tdoa";
  }
  return "?";
}

std::optional<RangingKind> rangingKindFromString(std::string_view text) {
  if (text == "ss-twr") return RangingKind::kSsTwr;
  if (text == "ds-twr") return RangingKind::kDsTwr;
  if (text == "tdoa") return RangingKind::kTdoa;
  return std::nullopt;
}

std::string_view toString(AnchorKind kind) {
  switch (kind) {
    case AnchorKind::kUwb: return "uwb";
    case AnchorKind::kUltrasonic: return "ultrasonic";
  }
  return "?";
}

std::optional<AnchorKind> anchorKindFromString(std::string_view text) {
  if (text == "uwb") return AnchorKind::kUwb;
  if (text == "ultrasonic") return AnchorKind::kUltrasonic;
  return std::nullopt;
}

const Anchor* Recording::findAnchor(std::uint32_t id) const {
  for (const Anchor& a : anchors) {
    if (a.id == id) return &a;
  }
  return nullptr;
}

const Vec3* Recording::findTagLeverArm(std::uint32_t tag_id) const {
  if (tags.empty()) return tag_id == 0 ? &meta.uwb_lever_arm_m : nullptr;
  for (const Tag& t : tags) {
    if (t.id == tag_id) return &t.p_b_tag;
  }
  return nullptr;
}

}  // namespace rilo
