#pragma once
// QoS of rilo's topics (writers and the matching readers).
//
//   topic     writer                                            reader (rilo listen, tests)
//   odometry  best-effort, volatile, keep-last 1                best-effort, keep-last `depth` (default 256)
//   pose      reliable, volatile, keep-last 10                  reliable, keep-last 10
//   status    reliable, transient-local, keep-last 32           reliable, transient-local, keep-last 64
//             (kept until acknowledged; for late joiners: the newest)
//   tf        reliable, volatile, keep-last 100                 reliable, keep-last 100
//   ranges    reliable, volatile, keep-last 10                  reliable, keep-last 10
//
// Odometry is sensor data at IMU rate: a late sample is worthless, so it is
// never retransmitted and never blocks (ROS 2 subscribers need the
// SensorDataQoS / best-effort profile; a reliable reader does not match).
// Pose and status are reliable; their writers use max_blocking_time 0, so a
// congested link makes dds_write return DDS_RETCODE_TIMEOUT instead of
// stalling the service. Status is transient-local so a late joiner gets the
// current status at once (the newest only). Its readers keep 64, so a
// subscriber that takes at least once per 64 statuses (a loaded machine, a
// fast replay whose 30 s ranging blackout lasts a few status periods) still
// sees every state the service went through, not only the last one. The
// writer keeps the last 32 until acknowledged: with one, a status lost on the
// wire (a loopback socket flooded by 800 Hz odometry) was repaired only with
// the newest, and a short degraded state never reached the subscriber. 32
// statuses of at most ~640 bytes stay under Cyclone's initial 30 kB of
// unacknowledged data per writer, past which a write with max_blocking_time 0
// fails with DDS_RETCODE_TIMEOUT; at the 1 Hz default they cover 32 s of a
// stalled reader. A late joiner gets the newest only once the existing
// readers have acknowledged the others (durability_service depth 1).
// TF is what tf2_ros's TransformBroadcaster and TransformListener use
// (reliable, volatile, depth 100), so rviz2 and every tf2 listener match; its
// writer does not block either (max_blocking_time 0).
#include <dds/dds.h>

#include <cstdint>
#include <memory>

#include "dds/topics.h"

namespace rilo::dds {

struct QosDeleter {
  void operator()(dds_qos_t* qos) const noexcept { dds_delete_qos(qos); }
};
using QosPtr = std::unique_ptr<dds_qos_t, QosDeleter>;

inline constexpr std::int32_t kPoseHistoryDepth = 10;
inline constexpr std::int32_t kDefaultOdometryReaderDepth = 256;
inline constexpr std::int32_t kStatusReaderDepth = 64;
inline constexpr std::int32_t kStatusWriterDepth = 32;  ///< kept until acknowledged (late joiners: the newest)
static_assert(kStatusReaderDepth >= kStatusWriterDepth, "a reader keeps at least what the writer repairs");
inline constexpr std::int32_t kTfHistoryDepth = 100;  ///< tf2_ros's DynamicBroadcasterQoS / DynamicListenerQoS

QosPtr writerQos(TopicKind kind);
/// `odometry_depth` is the keep-last depth of an odometry reader (> 0).
QosPtr readerQos(TopicKind kind, std::int32_t odometry_depth = kDefaultOdometryReaderDepth);

}  // namespace rilo::dds
