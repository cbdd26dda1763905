#pragma once
// Reader side of rilo's topics (`rilo listen`, tests): subscribes to any of
// the topics with QoS compatible with the service's writers (qos.h),
// waits on a waitset for data and takes samples as C++ values (messages.h).
// Not for the real-time path: taking allocates. Set-up and take errors throw
// std::runtime_error naming the DDS call and topic.
#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "dds/entity.h"
#include "dds/messages.h"
#include "dds/participant.h"
#include "dds/qos.h"
#include "dds/topics.h"

namespace rilo::dds {

struct SubscriberOptions {
  TopicNames topics;
  bool odometry = true;  ///< subscribe to the odometry topic
  bool pose = true;
  bool status = true;
  bool tf = false;       ///< subscribe to TF (topics.tf), e.g. to check it against the odometry
  bool ranges = false;   ///< subscribe to the judged ranges (topics.ranges; rilo view)
  std::int32_t odometry_depth = kDefaultOdometryReaderDepth;  ///< keep-last depth of the odometry reader
};

class Subscriber {
 public:
  /// The participant must outlive the subscriber.
  explicit Subscriber(const Participant& participant, SubscriberOptions options = {});
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;
  ~Subscriber();

  /// Blocks until a subscribed reader holds samples (true) or `timeout` passes (false).
  bool waitForData(std::chrono::nanoseconds timeout);

  /// Take every available sample of one topic, appending to `out`; returns how
  /// many were appended (0 when not subscribed).
  std::size_t takeOdometry(std::vector<OdometryMessage>& out);
  std::size_t takePose(std::vector<PoseMessage>& out);
  std::size_t takeStatus(std::vector<StatusMessage>& out);
  std::size_t takeTf(std::vector<TfMessage>& out);
  std::size_t takeRanges(std::vector<RangesMessage>& out);

  bool subscribed(TopicKind kind) const noexcept;
  /// Writers currently matched with the reader of `kind` (0 when not subscribed).
  std::uint32_t matchedPublishers(TopicKind kind) const;
  /// Blocks on a waitset until at least `count` writers match or `timeout` passes.
  bool waitForPublishers(TopicKind kind, std::uint32_t count, std::chrono::nanoseconds timeout) const;

  const SubscriberOptions& options() const noexcept { return options_; }

 private:
  struct Endpoint {
    Entity topic;
    Entity reader;
    Entity condition;  // read condition: any sample present
  };
  const Endpoint& endpointOf(TopicKind kind) const noexcept;

  dds_entity_t participant_;
  SubscriberOptions options_;
  Endpoint odometry_;
  Endpoint pose_;
  Endpoint status_;
  Endpoint tf_;
  Endpoint ranges_;
  Entity waitset_;  // declared last: deleted first
};

}  // namespace rilo::dds
