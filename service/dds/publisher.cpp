#include "dds/publisher.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <string>
#include <utility>

#include "dds/conversions.h"
#include "dds/dds_error.h"
#include "dds/qos.h"
#include "dds/wait.h"

namespace rilo::dds {
namespace {

Entity createTopic(dds_entity_t participant, const dds_topic_descriptor_t& descriptor, const std::string& name) {
  const dds_entity_t topic = dds_create_topic(participant, &descriptor, name.c_str(), nullptr, nullptr);
  return Entity(checkEntity(topic, "dds_create_topic", "topic '" + name + "', type " + descriptor.m_typename));
}

Entity createWriter(dds_entity_t participant, const Entity& topic, TopicKind kind, const std::string& name) {
  const QosPtr qos = writerQos(kind);
  const dds_entity_t writer = dds_create_writer(participant, topic.get(), qos.get(), nullptr);
  return Entity(checkEntity(writer, "dds_create_writer", "topic '" + name + "'"));
}

bool finite(const NavigationState& s) noexcept {
  return s.p_w_b.allFinite() && s.v_w_b.allFinite() && s.q_w_b.coeffs().allFinite() && s.omega_b.allFinite() &&
         s.q_w_b.squaredNorm() > 0.5;  // a zero quaternion has no orientation
}

/// Checks shared by the odometry and pose paths; ok() when the state may be written.
WriteStatus checkState(const NavigationState& s) noexcept {
  if (!s.valid) return {DDS_RETCODE_PRECONDITION_NOT_MET, "navigation state not valid (estimator not initialized)"};
  if (s.t_ns < 0) return {DDS_RETCODE_BAD_PARAMETER, "negative t_ns"};
  if (!finite(s)) return {DDS_RETCODE_BAD_PARAMETER, "non-finite navigation state"};
  return {};
}

template <std::size_t N>
void copyTruncated(const char* src, std::size_t src_capacity, std::array<char, N>& dst) noexcept {
  std::size_t n = 0;
  while (n < src_capacity && n + 1 < N && src[n] != '\0') ++n;
  std::memcpy(dst.data(), src, n);
  dst[n] = '\0';
}

}  // namespace

Publisher::Publisher(const Participant& participant, PublisherOptions options)
    : participant_(participant.handle()), options_(std::move(options)) {
  const TopicNames& names = options_.topics;
  odometry_topic_ = createTopic(participant_, nav_msgs_msg_dds__Odometry__desc, names.odometry);
  pose_topic_ = createTopic(participant_, geometry_msgs_msg_dds__PoseWithCovarianceStamped__desc, names.pose);
  status_topic_ = createTopic(participant_, rilo_msg_dds__Status__desc, names.status);
  odometry_writer_ = createWriter(participant_, odometry_topic_, TopicKind::kOdometry, names.odometry);
  pose_writer_ = createWriter(participant_, pose_topic_, TopicKind::kPose, names.pose);
  status_writer_ = createWriter(participant_, status_topic_, TopicKind::kStatus, names.status);
  if (!names.tf.empty()) {
    tf_topic_ = createTopic(participant_, tf2_msgs_msg_dds__TFMessage__desc, names.tf);
    tf_writer_ = createWriter(participant_, tf_topic_, TopicKind::kTf, names.tf);
  }
  if (!names.ranges.empty()) {
    ranges_topic_ = createTopic(participant_, rilo_msg_dds__Ranges__desc, names.ranges);
    ranges_writer_ = createWriter(participant_, ranges_topic_, TopicKind::kRanges, names.ranges);
  }
  refreshStampOffset();

  // Strings are set once; the publish calls only write numbers.
  odometry_.header.frame_id = options_.frames.world.data();
  odometry_.child_frame_id = options_.frames.body.data();
  pose_.header.frame_id = options_.frames.world.data();
  status_.header.frame_id = status_frame_id_.data();
  status_.state_name = state_name_.data();
  status_.last_fault = last_fault_.data();
  status_.reason = reason_.data();
  transform_.header.frame_id = options_.frames.world.data();
  transform_.child_frame_id = options_.frames.body.data();
  tf_.transforms._buffer = &transform_;  // not owned (_release false): never freed by Cyclone
  tf_.transforms._length = 1;
  tf_.transforms._maximum = 1;
  tf_.transforms._release = false;
  ranges_.header.frame_id = options_.frames.world.data();
  ranges_.ranges._buffer = range_readings_.data();  // not owned, as the TF sample's
  ranges_.ranges._maximum = static_cast<std::uint32_t>(kMaxRanges);
  ranges_.ranges._length = 0;
  ranges_.ranges._release = false;

  // Keyless topics have one instance. Registering it keeps Cyclone's instance
  // entry alive; otherwise a write with no reader holding the instance
  // creates and garbage-collects it on every write (measured: 2.5 more
  // allocations per write on average with Cyclone 0.10.2).
  dds_instance_handle_t instance = 0;
  checkReturn(dds_register_instance(odometry_writer_.get(), &instance, &odometry_), "dds_register_instance",
              "topic '" + names.odometry + "'");
  checkReturn(dds_register_instance(pose_writer_.get(), &instance, &pose_), "dds_register_instance",
              "topic '" + names.pose + "'");
  checkReturn(dds_register_instance(status_writer_.get(), &instance, &status_), "dds_register_instance",
              "topic '" + names.status + "'");
  if (tf_writer_) {
    checkReturn(dds_register_instance(tf_writer_.get(), &instance, &tf_), "dds_register_instance",
                "topic '" + names.tf + "'");
  }
  if (ranges_writer_) {
    checkReturn(dds_register_instance(ranges_writer_.get(), &instance, &ranges_), "dds_register_instance",
                "topic '" + names.ranges + "'");
  }
}

Publisher::~Publisher() = default;

void Publisher::refreshStampOffset() noexcept {
  if (options_.stamp_clock != StampClock::kSystem) return;
  // The two clocks only part at a step of the wall clock (NTP slews both
  // rates alike); each reading carries tens of ns of noise. Keeping the offset
  // until it really moved keeps one sample's odometry and TF stamps equal and
  // the stamps free of that jitter.
  const std::int64_t measured = systemMinusMonotonicNs();
  const std::int64_t current = stamp_offset_ns_.load(std::memory_order_relaxed);
  if (current == 0 || std::llabs(measured - current) > kStampStepNs) {
    stamp_offset_ns_.store(measured, std::memory_order_relaxed);
  }
}

WriteStatus Publisher::publishOdometry(const NavigationState& state) noexcept {
  if (const WriteStatus s = checkState(state); !s.ok()) return s;
  const std::int64_t offset_ns = stampOffsetNs();
  fillOdometry(state, odometry_, offset_ns);
  return {dds_write_ts(odometry_writer_.get(), &odometry_, state.t_ns + offset_ns)};
}

WriteStatus Publisher::publishPose(const NavigationState& state) noexcept {
  if (const WriteStatus s = checkState(state); !s.ok()) return s;
  const std::int64_t offset_ns = stampOffsetNs();
  fillPose(state, pose_, offset_ns);
  return {dds_write_ts(pose_writer_.get(), &pose_, state.t_ns + offset_ns)};
}

WriteStatus Publisher::publishTransform(const NavigationState& state) noexcept {
  if (!tf_writer_) return {};
  if (const WriteStatus s = checkState(state); !s.ok()) return s;
  const std::int64_t offset_ns = stampOffsetNs();
  fillTransform(state, transform_, offset_ns);
  return {dds_write_ts(tf_writer_.get(), &tf_, state.t_ns + offset_ns)};
}

WriteStatus Publisher::publishRanges(std::int64_t t_ns, std::span<const RangeReading> ranges) noexcept {
  if (!ranges_writer_) return {};
  if (t_ns < 0) return {DDS_RETCODE_BAD_PARAMETER, "negative t_ns"};
  const std::size_t n = std::min(ranges.size(), kMaxRanges);
  for (std::size_t i = 0; i < n; ++i) {
    const RangeReading& r = ranges[i];
    range_readings_[i] = {r.anchor_id, r.range_m, r.predicted_m, r.residual_m, r.weight, r.nlos, r.t_offset_ns};
  }
  ranges_.ranges._length = static_cast<std::uint32_t>(n);
  const std::int64_t offset_ns = stampOffsetNs();
  toRosTime(t_ns + offset_ns, ranges_.header.stamp);
  return {dds_write_ts(ranges_writer_.get(), &ranges_, t_ns + offset_ns)};
}

WriteStatus Publisher::publishStatus(const ServiceStatus& status) noexcept {
  if (status.t_ns < 0) return {DDS_RETCODE_BAD_PARAMETER, "negative t_ns"};
  const std::int64_t offset_ns = stampOffsetNs();
  fillStatus(status, status_, offset_ns);
  const char* name = trackingStateName(status.state);
  copyTruncated(name, std::strlen(name), state_name_);
  copyTruncated(status.last_fault.data(), status.last_fault.size(), last_fault_);
  copyTruncated(status.reason.data(), status.reason.size(), reason_);
  return {dds_write_ts(status_writer_.get(), &status_, status.t_ns + offset_ns)};
}

dds_entity_t Publisher::writerOf(TopicKind kind) const noexcept {
  switch (kind) {
    case TopicKind::kOdometry: return odometry_writer_.get();
    case TopicKind::kPose: return pose_writer_.get();
    case TopicKind::kTf: return tf_writer_.get();
    case TopicKind::kRanges: return ranges_writer_.get();
    case TopicKind::kStatus: break;
  }
  return status_writer_.get();
}

std::uint32_t Publisher::matchedSubscribers(TopicKind kind) const {
  if (writerOf(kind) == 0) return 0;  // no TF topic
  dds_publication_matched_status_t matched{};
  checkReturn(dds_get_publication_matched_status(writerOf(kind), &matched), "dds_get_publication_matched_status",
              "topic '" + options_.topics.of(kind) + "'");
  return matched.current_count;
}

bool Publisher::waitForSubscribers(TopicKind kind, std::uint32_t count, std::chrono::nanoseconds timeout) const {
  return waitForMatch(participant_, writerOf(kind), DDS_PUBLICATION_MATCHED_STATUS, options_.topics.of(kind),
                      timeout, [&] { return matchedSubscribers(kind) >= count; });
}

bool Publisher::waitForAcknowledgments(std::chrono::nanoseconds timeout) const {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (TopicKind kind : {TopicKind::kPose, TopicKind::kStatus}) {
    const auto remaining =
        std::max(std::chrono::nanoseconds::zero(),
                 std::chrono::duration_cast<std::chrono::nanoseconds>(deadline - std::chrono::steady_clock::now()));
    const dds_return_t rc = dds_wait_for_acks(writerOf(kind), remaining.count());
    if (rc == DDS_RETCODE_TIMEOUT) return false;
    checkReturn(rc, "dds_wait_for_acks", "topic '" + options_.topics.of(kind) + "'");
  }
  return true;
}

}  // namespace rilo::dds
