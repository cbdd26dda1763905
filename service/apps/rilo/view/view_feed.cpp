#include "view_feed.h"

#include <chrono>
#include <vector>

namespace rilo::tool {

void feedView(dds::Subscriber& subscriber, ViewState& state, const std::function<bool()>& keep_going) {
  std::vector<dds::OdometryMessage> odometry;
  std::vector<dds::PoseMessage> poses;
  std::vector<dds::StatusMessage> statuses;
  std::vector<dds::RangesMessage> ranges;
  while (keep_going()) {
    if (!subscriber.waitForData(std::chrono::milliseconds(100))) continue;
    odometry.clear();
    poses.clear();
    statuses.clear();
    ranges.clear();
    subscriber.takeOdometry(odometry);
    subscriber.takePose(poses);
    subscriber.takeStatus(statuses);
    subscriber.takeRanges(ranges);
    for (const auto& m : poses) state.onPose(m);
    for (const auto& m : odometry) state.onOdometry(m);  // each: the rate and counts are the topic's
    for (const auto& m : statuses) state.onStatus(m);
    for (const auto& m : ranges) state.onRanges(m);
  }
}

}  // namespace rilo::tool
