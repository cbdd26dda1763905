#pragma once
// Writes rilo's topics (topics.h, QoS in qos.h) from the service: odometry,
// pose, status, and TF (world -> body) unless its topic name is empty.
//
// Set-up (constructor) throws std::runtime_error naming the failing DDS call
// and topic. The publish calls are for the real-time path: noexcept, no heap
// allocation in this code (the samples and their frame-id strings are
// allocated once here), and failures come back as a WriteStatus. Each
// publishX() uses its own pre-allocated sample, so different topics may be
// published from different threads, but one topic from one thread at a time.
// Cyclone's own dds_write allocation behaviour is measured in
// tests/dds/publish_allocation_test.cpp (see README.md).
#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <span>
#include <string>

#include "dds/entity.h"
#include "dds/messages.h"
#include "dds/participant.h"
#include "dds/stamp_clock.h"
#include "dds/topics.h"
#include "geometry_msgs.h"
#include "nav_msgs.h"
#include "rilo_msgs.h"
#include "tf2_msgs.h"
#include "runtime/navigation_state.h"
#include "runtime/service_status.h"

namespace rilo::dds {

struct PublisherOptions {
  TopicNames topics;
  FrameIds frames;
  StampClock stamp_clock = StampClock::kSystem;  ///< the clock of every header stamp (stamp_clock.h)
};

/// Outcome of one publish call. `reason` is a static string when the sample
/// was rejected before reaching DDS (invalid state, bad timestamp), else null.
struct WriteStatus {
  dds_return_t code = DDS_RETCODE_OK;
  const char* reason = nullptr;

  bool ok() const noexcept { return code == DDS_RETCODE_OK; }
  /// Static text, no allocation.
  const char* text() const noexcept { return reason != nullptr ? reason : dds_strretcode(code); }
};

class Publisher {
 public:
  /// The participant must outlive the publisher.
  explicit Publisher(const Participant& participant, PublisherOptions options = {});
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;
  Publisher(Publisher&&) = delete;  // the samples point into this object's strings
  Publisher& operator=(Publisher&&) = delete;
  ~Publisher();

  /// nav_msgs/Odometry of `state` (IMU rate). Source timestamp = header.stamp
  /// = state.t_ns + stampOffsetNs().
  [[nodiscard]] WriteStatus publishOdometry(const NavigationState& state) noexcept;
  /// geometry_msgs/PoseWithCovarianceStamped of `state` (smoother rate).
  [[nodiscard]] WriteStatus publishPose(const NavigationState& state) noexcept;
  /// tf2_msgs/TFMessage with one transform world -> body (the odometry's
  /// pose, same stamp). Without a TF topic: OK, nothing written.
  [[nodiscard]] WriteStatus publishTransform(const NavigationState& state) noexcept;
  /// rilo_msgs/Ranges of one ranging epoch at `t_ns` (the first kMaxRanges of
  /// `ranges`). Without a ranges topic: OK, nothing written.
  static constexpr std::size_t kMaxRanges = 64;
  [[nodiscard]] WriteStatus publishRanges(std::int64_t t_ns, std::span<const RangeReading> ranges) noexcept;
  [[nodiscard]] WriteStatus publishStatus(const ServiceStatus& status) noexcept;

  /// A change of the offset smaller than this is reading noise, not a step of
  /// the wall clock, and is not taken.
  static constexpr std::int64_t kStampStepNs = 100'000;
  /// Re-reads system time minus CLOCK_MONOTONIC (stamp_clock.h; no-op with
  /// StampClock::kMonotonic) and takes it when it moved by more than
  /// kStampStepNs. Any thread; the publish calls pick the new offset up at
  /// their next write.
  void refreshStampOffset() noexcept;
  /// What the publish calls add to t_ns for header stamps (0 when monotonic).
  std::int64_t stampOffsetNs() const noexcept { return stamp_offset_ns_.load(std::memory_order_relaxed); }
  bool publishesTf() const noexcept { return static_cast<bool>(tf_writer_); }
  bool publishesRanges() const noexcept { return static_cast<bool>(ranges_writer_); }

  /// Readers currently matched with the writer of `kind` (throws on DDS error).
  std::uint32_t matchedSubscribers(TopicKind kind) const;
  /// Blocks on a waitset until at least `count` readers match or `timeout` passes.
  bool waitForSubscribers(TopicKind kind, std::uint32_t count, std::chrono::nanoseconds timeout) const;

  /// Blocks until every matched reader acknowledged the reliable topics'
  /// (pose, status) samples or `timeout` passes (false). For orderly
  /// shutdown; throws on DDS errors other than the timeout.
  bool waitForAcknowledgments(std::chrono::nanoseconds timeout) const;

  const PublisherOptions& options() const noexcept { return options_; }

 private:
  dds_entity_t writerOf(TopicKind kind) const noexcept;

  dds_entity_t participant_;
  PublisherOptions options_;
  std::string status_frame_id_;  // empty: status has no frame
  // Topics before writers: members are destroyed in reverse order.
  std::atomic<std::int64_t> stamp_offset_ns_{0};
  Entity odometry_topic_;
  Entity pose_topic_;
  Entity status_topic_;
  Entity tf_topic_;      // empty without a TF topic name
  Entity ranges_topic_;  // empty without a ranges topic name
  Entity odometry_writer_;
  Entity pose_writer_;
  Entity status_writer_;
  Entity tf_writer_;
  Entity ranges_writer_;
  // Pre-allocated samples; string members point into options_ / the buffers below.
  nav_msgs_msg_dds__Odometry_ odometry_{};
  geometry_msgs_msg_dds__PoseWithCovarianceStamped_ pose_{};
  rilo_msg_dds__Status_ status_{};
  geometry_msgs_msg_dds__TransformStamped_ transform_{};  // the TF sample's one element
  tf2_msgs_msg_dds__TFMessage_ tf_{};
  std::array<rilo_msg_dds__RangeReading_, kMaxRanges> range_readings_{};  // the ranges sample's sequence
  rilo_msg_dds__Ranges_ ranges_{};
  std::array<char, 16> state_name_{};
  std::array<char, 128> last_fault_{};
  std::array<char, 160> reason_{};
};

}  // namespace rilo::dds
