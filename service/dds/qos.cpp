#include "dds/qos.h"

#include <new>
#include <stdexcept>
#include <string>

namespace rilo::dds {
namespace {

QosPtr newQos() {
  QosPtr qos(dds_create_qos());
  if (!qos) throw std::bad_alloc();
  return qos;
}

}  // namespace

QosPtr writerQos(TopicKind kind) {
  QosPtr qos = newQos();
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  switch (kind) {
    case TopicKind::kOdometry:
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, 1);
      break;
    case TopicKind::kPose:
    case TopicKind::kRanges:  // one sample per ranging epoch, like the pose
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kPoseHistoryDepth);
      break;
    case TopicKind::kStatus:
      // Keeps the last kStatusWriterDepth until acknowledged, so a status lost
      // on the wire (a loopback socket full of odometry) is repaired itself,
      // not replaced by the newest; Cyclone keeps
      // durability_service.history.depth (1) for late joiners (qos.h).
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kStatusWriterDepth);
      dds_qset_durability_service(qos.get(), 0, DDS_HISTORY_KEEP_LAST, 1, DDS_LENGTH_UNLIMITED, DDS_LENGTH_UNLIMITED,
                                  DDS_LENGTH_UNLIMITED);
      break;
    case TopicKind::kTf:
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kTfHistoryDepth);
      break;
  }
  return qos;
}

QosPtr readerQos(TopicKind kind, std::int32_t odometry_depth) {
  if (odometry_depth <= 0) {
    throw std::invalid_argument("readerQos: odometry_depth must be > 0, got " + std::to_string(odometry_depth));
  }
  QosPtr qos = newQos();
  dds_qset_durability(qos.get(), DDS_DURABILITY_VOLATILE);
  switch (kind) {
    case TopicKind::kOdometry:
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_BEST_EFFORT, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, odometry_depth);
      break;
    case TopicKind::kPose:
    case TopicKind::kRanges:  // one sample per ranging epoch, like the pose
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kPoseHistoryDepth);
      break;
    case TopicKind::kStatus:
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_durability(qos.get(), DDS_DURABILITY_TRANSIENT_LOCAL);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kStatusReaderDepth);
      break;
    case TopicKind::kTf:
      dds_qset_reliability(qos.get(), DDS_RELIABILITY_RELIABLE, 0);
      dds_qset_history(qos.get(), DDS_HISTORY_KEEP_LAST, kTfHistoryDepth);
      break;
  }
  return qos;
}

}  // namespace rilo::dds
