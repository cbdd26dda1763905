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

std::optional<Vec3> Recording::findTagLeverArm(std::uint32_t tag_id) const {
  if (tags.empty()) return tag_id == 0 ? std::optional<Vec3>(meta.uwbLeverArm()) : std::nullopt;
  for (const Tag& t : tags) {
    if (t.id == tag_id) return t.p_b_tag;
  }
  return std::nullopt;
}

namespace {

std::vector<Vec3> anchorsOfKindById(const std::vector<Anchor>& anchors, AnchorKind kind) {
  std::vector<Vec3> p_w_anchors;
  for (const Anchor& a : anchors) {
    if (a.kind != kind) continue;
    if (p_w_anchors.size() <= a.id) p_w_anchors.resize(a.id + 1, Vec3::Constant(1e6));
    p_w_anchors[a.id] = a.p_w_anchor;
  }
  return p_w_anchors;
}

}  // namespace

std::vector<Vec3> uwbAnchorsById(const std::vector<Anchor>& anchors) {
  return anchorsOfKindById(anchors, AnchorKind::kUwb);
}

std::vector<Vec3> ultrasonicBeaconsById(const std::vector<Anchor>& anchors) {
  return anchorsOfKindById(anchors, AnchorKind::kUltrasonic);
}

}  // namespace rilo
