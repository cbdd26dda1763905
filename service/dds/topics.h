#pragma once
// rilo's topics, their ROS 2 names and the frame ids written into the
// messages. Names use the ROS 2 mapping: DDS topic "rt/<ros topic without the
// leading slash>", so "rt/rilo/odometry" is /rilo/odometry for ROS 2 tools.
#include <cstdint>
#include <string>
#include <string_view>

namespace rilo::dds {

enum class TopicKind : std::uint8_t { kOdometry = 0, kPose = 1, kStatus = 2, kTf = 3, kRanges = 4 };

inline constexpr std::string_view topicKindName(TopicKind kind) noexcept {
  switch (kind) {
    case TopicKind::kOdometry: return "odometry";
    case TopicKind::kPose: return "pose";
    case TopicKind::kStatus: return "status";
    case TopicKind::kTf: return "tf";
    case TopicKind::kRanges: return "ranges";
  }
  return "unknown";
}

struct TopicNames {
  std::string odometry = "rt/rilo/odometry";  ///< nav_msgs/Odometry at IMU rate
  std::string pose = "rt/rilo/pose";          ///< geometry_msgs/PoseWithCovarianceStamped, smoothed
  std::string status = "rt/rilo/status";      ///< rilo_msgs/Status
  /// tf2_msgs/TFMessage world -> body at the odometry rate (ROS 2 /tf); empty: no TF.
  std::string tf = "rt/tf";
  /// rilo_msgs/Ranges: each ranging epoch's ranges as the estimator judged them.
  std::string ranges = "rt/rilo/ranges";

  const std::string& of(TopicKind kind) const noexcept {
    switch (kind) {
      case TopicKind::kOdometry: return odometry;
      case TopicKind::kPose: return pose;
      case TopicKind::kTf: return tf;
      case TopicKind::kRanges: return ranges;
      case TopicKind::kStatus: break;
    }
    return status;
  }
};

/// REP-105 frame ids: poses are of `body` in `world` (header.frame_id = world,
/// Odometry and TF child_frame_id = body). REP-103: x forward, y left, z up
/// (ENU world). rilo's world is fixed by the surveyed anchors, so it is REP-105's
/// `map`; with no odometry frame of its own, TF is `map -> base_link` directly.
struct FrameIds {
  std::string world = "map";
  std::string body = "base_link";
};

}  // namespace rilo::dds
