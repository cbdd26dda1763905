// The generated types carry exactly the names and shapes ROS 2 uses on DDS,
// which is what rmw_cyclonedds matches on.
#include <gtest/gtest.h>

#include <string>
#include <type_traits>

#include "geometry_msgs.h"
#include "nav_msgs.h"
#include "rilo_msgs.h"

namespace {

TEST(DdsIdlTypes, RosTypeNames) {
  EXPECT_EQ(std::string(nav_msgs_msg_dds__Odometry__desc.m_typename), "nav_msgs::msg::dds_::Odometry_");
  EXPECT_EQ(std::string(geometry_msgs_msg_dds__PoseWithCovarianceStamped__desc.m_typename),
            "geometry_msgs::msg::dds_::PoseWithCovarianceStamped_");
  EXPECT_EQ(std::string(rilo_msg_dds__Status__desc.m_typename), "rilo::msg::dds_::Status_");
  EXPECT_EQ(std::string(std_msgs_msg_dds__Header__desc.m_typename), "std_msgs::msg::dds_::Header_");
  EXPECT_EQ(std::string(builtin_interfaces_msg_dds__Time__desc.m_typename), "builtin_interfaces::msg::dds_::Time_");
}

TEST(DdsIdlTypes, KeylessTopics) {
  // ROS 2 messages have no keys: one instance per topic.
  EXPECT_EQ(nav_msgs_msg_dds__Odometry__desc.m_nkeys, 0u);
  EXPECT_EQ(geometry_msgs_msg_dds__PoseWithCovarianceStamped__desc.m_nkeys, 0u);
  EXPECT_EQ(rilo_msg_dds__Status__desc.m_nkeys, 0u);
}

TEST(DdsIdlTypes, FieldShapes) {
  nav_msgs_msg_dds__Odometry_ odometry{};
  static_assert(std::is_same_v<decltype(odometry.header.stamp.sec), int32_t>);
  static_assert(std::is_same_v<decltype(odometry.header.stamp.nanosec), uint32_t>);
  static_assert(std::is_same_v<decltype(odometry.header.frame_id), char*>);
  static_assert(std::is_same_v<decltype(odometry.child_frame_id), char*>);
  static_assert(sizeof(odometry.pose.covariance) == 36 * sizeof(double));
  static_assert(sizeof(odometry.twist.covariance) == 36 * sizeof(double));
  static_assert(std::is_same_v<decltype(odometry.pose.pose.orientation.w), double>);
  rilo_msg_dds__Status_ status{};
  static_assert(std::is_same_v<decltype(status.state), uint8_t>);
  static_assert(std::is_same_v<decltype(status.imu_samples), uint64_t>);
  static_assert(std::is_same_v<decltype(status.last_relinearized), uint32_t>);
  EXPECT_EQ(odometry.child_frame_id, nullptr);
  EXPECT_EQ(status.last_fault, nullptr);
}

}  // namespace
