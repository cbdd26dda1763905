#include "dds/subscriber.h"

#include <array>
#include <stdexcept>
#include <utility>

#include "dds/conversions.h"
#include "dds/dds_error.h"
#include "dds/wait.h"
#include "geometry_msgs.h"
#include "nav_msgs.h"
#include "rilo_msgs.h"
#include "tf2_msgs.h"

namespace rilo::dds {
namespace {

std::string topicLabel(const std::string& name) { return "topic '" + name + "'"; }

/// Returns loaned samples even when a conversion throws.
class LoanGuard {
 public:
  LoanGuard(dds_entity_t reader, void** samples, std::int32_t count) noexcept
      : reader_(reader), samples_(samples), count_(count) {}
  ~LoanGuard() { static_cast<void>(release()); }
  LoanGuard(const LoanGuard&) = delete;
  LoanGuard& operator=(const LoanGuard&) = delete;
  dds_return_t release() noexcept {
    dds_return_t rc = DDS_RETCODE_OK;
    if (count_ > 0) rc = dds_return_loan(reader_, samples_, count_);
    count_ = 0;
    return rc;
  }

 private:
  dds_entity_t reader_;
  void** samples_;
  std::int32_t count_;
};

template <class Sample, class Message, class Convert>
std::size_t takeAll(dds_entity_t reader, const std::string& topic, std::vector<Message>& out, Convert convert) {
  constexpr std::uint32_t kBatch = 64;
  std::size_t taken = 0;
  for (;;) {
    std::array<void*, kBatch> samples{};  // null: Cyclone lends its own buffers
    std::array<dds_sample_info_t, kBatch> infos{};
    const dds_return_t n = dds_take(reader, samples.data(), infos.data(), kBatch, kBatch);
    if (n < 0) throwDdsError("dds_take", topicLabel(topic), n);
    LoanGuard loan(reader, samples.data(), n);
    for (std::size_t i = 0; i < static_cast<std::size_t>(n); ++i) {
      if (!infos[i].valid_data) continue;  // instance state change only
      Message message = convert(*static_cast<const Sample*>(samples[i]));
      message.source_timestamp_ns = infos[i].source_timestamp;
      out.push_back(std::move(message));
      ++taken;
    }
    checkReturn(loan.release(), "dds_return_loan", topicLabel(topic));
    if (static_cast<std::uint32_t>(n) < kBatch) return taken;
  }
}

}  // namespace

Subscriber::Subscriber(const Participant& participant, SubscriberOptions options)
    : participant_(participant.handle()), options_(std::move(options)) {
  waitset_ = Entity(checkEntity(dds_create_waitset(participant_), "dds_create_waitset", "subscriber"));
  auto open = [&](Endpoint& ep, TopicKind kind, const dds_topic_descriptor_t& descriptor) {
    const std::string& name = options_.topics.of(kind);
    ep.topic = Entity(checkEntity(dds_create_topic(participant_, &descriptor, name.c_str(), nullptr, nullptr),
                                  "dds_create_topic", topicLabel(name) + ", type " + descriptor.m_typename));
    const QosPtr qos = readerQos(kind, options_.odometry_depth);
    ep.reader = Entity(checkEntity(dds_create_reader(participant_, ep.topic.get(), qos.get(), nullptr),
                                   "dds_create_reader", topicLabel(name)));
    ep.condition = Entity(checkEntity(dds_create_readcondition(ep.reader.get(), DDS_ANY_STATE),
                                      "dds_create_readcondition", topicLabel(name)));
    checkReturn(dds_waitset_attach(waitset_.get(), ep.condition.get(), ep.reader.get()), "dds_waitset_attach",
                topicLabel(name));
  };
  if (options_.odometry) open(odometry_, TopicKind::kOdometry, nav_msgs_msg_dds__Odometry__desc);
  if (options_.pose) open(pose_, TopicKind::kPose, geometry_msgs_msg_dds__PoseWithCovarianceStamped__desc);
  if (options_.status) open(status_, TopicKind::kStatus, rilo_msg_dds__Status__desc);
  if (options_.tf) {
    if (options_.topics.tf.empty()) throw std::invalid_argument("Subscriber: tf requested but the TF topic name is empty");
    open(tf_, TopicKind::kTf, tf2_msgs_msg_dds__TFMessage__desc);
  }
  if (options_.ranges) {
    if (options_.topics.ranges.empty()) {
      throw std::invalid_argument("Subscriber: ranges requested but the ranges topic name is empty");
    }
    open(ranges_, TopicKind::kRanges, rilo_msg_dds__Ranges__desc);
  }
}

Subscriber::~Subscriber() {
  // The waitset must go before the conditions attached to it.
  waitset_.reset();
}

bool Subscriber::waitForData(std::chrono::nanoseconds timeout) {
  const dds_return_t rc = dds_waitset_wait(waitset_.get(), nullptr, 0, timeout.count());
  if (rc < 0) throwDdsError("dds_waitset_wait", "subscriber", rc);
  return rc > 0;
}

std::size_t Subscriber::takeOdometry(std::vector<OdometryMessage>& out) {
  if (!odometry_.reader) return 0;
  return takeAll<nav_msgs_msg_dds__Odometry_>(odometry_.reader.get(), options_.topics.odometry, out,
                                              [](const nav_msgs_msg_dds__Odometry_& m) { return toOdometryMessage(m); });
}

std::size_t Subscriber::takePose(std::vector<PoseMessage>& out) {
  if (!pose_.reader) return 0;
  return takeAll<geometry_msgs_msg_dds__PoseWithCovarianceStamped_>(
      pose_.reader.get(), options_.topics.pose, out,
      [](const geometry_msgs_msg_dds__PoseWithCovarianceStamped_& m) { return toPoseMessage(m); });
}

std::size_t Subscriber::takeStatus(std::vector<StatusMessage>& out) {
  if (!status_.reader) return 0;
  return takeAll<rilo_msg_dds__Status_>(status_.reader.get(), options_.topics.status, out,
                                        [](const rilo_msg_dds__Status_& m) { return toStatusMessage(m); });
}

std::size_t Subscriber::takeTf(std::vector<TfMessage>& out) {
  if (!tf_.reader) return 0;
  return takeAll<tf2_msgs_msg_dds__TFMessage_>(tf_.reader.get(), options_.topics.tf, out,
                                               [](const tf2_msgs_msg_dds__TFMessage_& m) { return toTfMessage(m); });
}

std::size_t Subscriber::takeRanges(std::vector<RangesMessage>& out) {
  if (!ranges_.reader) return 0;
  return takeAll<rilo_msg_dds__Ranges_>(ranges_.reader.get(), options_.topics.ranges, out,
                                        [](const rilo_msg_dds__Ranges_& m) { return toRangesMessage(m); });
}

const Subscriber::Endpoint& Subscriber::endpointOf(TopicKind kind) const noexcept {
  switch (kind) {
    case TopicKind::kOdometry: return odometry_;
    case TopicKind::kPose: return pose_;
    case TopicKind::kTf: return tf_;
    case TopicKind::kRanges: return ranges_;
    case TopicKind::kStatus: break;
  }
  return status_;
}

bool Subscriber::subscribed(TopicKind kind) const noexcept { return static_cast<bool>(endpointOf(kind).reader); }

std::uint32_t Subscriber::matchedPublishers(TopicKind kind) const {
  const Endpoint& ep = endpointOf(kind);
  if (!ep.reader) return 0;
  dds_subscription_matched_status_t matched{};
  checkReturn(dds_get_subscription_matched_status(ep.reader.get(), &matched), "dds_get_subscription_matched_status",
              topicLabel(options_.topics.of(kind)));
  return matched.current_count;
}

bool Subscriber::waitForPublishers(TopicKind kind, std::uint32_t count, std::chrono::nanoseconds timeout) const {
  const Endpoint& ep = endpointOf(kind);
  if (!ep.reader) return count == 0;
  return waitForMatch(participant_, ep.reader.get(), DDS_SUBSCRIPTION_MATCHED_STATUS, options_.topics.of(kind), timeout,
                      [&] { return matchedPublishers(kind) >= count; });
}

}  // namespace rilo::dds
