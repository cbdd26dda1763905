// Publisher and Subscriber through real Cyclone DDS: two participants of one
// process on a private domain, loopback only.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <ctime>
#include <stdexcept>
#include <random>
#include <string>
#include <vector>

#include "dds/conversions.h"
#include "dds/publisher.h"
#include "dds/qos.h"
#include "dds/subscriber.h"
#include "dds_test_support.h"

namespace rilo::dds {
namespace {

using namespace std::chrono_literals;
using testing::kMatchTimeout;

std::string testName() { return ::testing::UnitTest::GetInstance()->current_test_info()->name(); }

/// Takes from `take` until `count` messages arrived or 10 s passed.
template <class Message, class Take>
std::vector<Message> receive(Subscriber& sub, std::size_t count, Take take) {
  std::vector<Message> out;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (out.size() < count && std::chrono::steady_clock::now() < deadline) {
    if (sub.waitForData(100ms)) take(out);
  }
  return out;
}

void expectOdometryEquals(const OdometryMessage& m, const NavigationState& s, const FrameIds& frames) {
  EXPECT_EQ(m.stamp_ns, s.t_ns);
  EXPECT_EQ(m.source_timestamp_ns, s.t_ns);
  EXPECT_EQ(m.frame_id, frames.world);
  EXPECT_EQ(m.child_frame_id, frames.body);
  EXPECT_EQ(m.p_w_b, s.p_w_b);
  EXPECT_EQ(m.q_w_b.coeffs(), s.q_w_b.normalized().coeffs());
  EXPECT_EQ(m.pose_covariance, rosPoseCovariance(s));
  const BodyTwist twist = bodyTwist(s);
  EXPECT_EQ(m.v_b, twist.v_b);
  EXPECT_EQ(m.omega_b, s.omega_b);
  EXPECT_EQ(m.twist_covariance, twist.covariance);
}

class DdsPubSub : public ::testing::Test {
 protected:
  DdsPubSub()
      : names_(testing::uniqueTopicNames(testName())),
        pub_participant_(testing::loopbackOptions()),
        sub_participant_(testing::loopbackOptions()) {}

  /// Stamps on the samples' own clock, so they compare exactly (the system
  /// clock's offset has its own test below).
  PublisherOptions publisherOptions() const {
    PublisherOptions po;
    po.topics = names_;
    po.stamp_clock = StampClock::kMonotonic;
    return po;
  }
  /// A reader of the status topic alone.
  SubscriberOptions statusOnly() const {
    SubscriberOptions so;
    so.topics = names_;
    so.odometry = false;
    so.pose = false;
    return so;
  }

  TopicNames names_;
  Participant pub_participant_;
  Participant sub_participant_;
};

TEST_F(DdsPubSub, OdometryArrivesWithExactFields) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, kMatchTimeout));
  ASSERT_TRUE(sub.waitForPublishers(TopicKind::kOdometry, 1, kMatchTimeout));
  EXPECT_EQ(pub.matchedSubscribers(TopicKind::kOdometry), 1u);

  std::mt19937 rng(21);
  std::vector<NavigationState> sent;
  for (int i = 0; i < 20; ++i) {
    sent.push_back(testing::randomState(rng, 10'000'000'000 + i * 5'000'000));
    const WriteStatus ws = pub.publishOdometry(sent.back());
    ASSERT_TRUE(ws.ok()) << ws.text();
  }
  const auto got = receive<OdometryMessage>(sub, sent.size(), [&](auto& out) { sub.takeOdometry(out); });
  ASSERT_EQ(got.size(), sent.size());  // in-process delivery, reader depth 256: nothing lost
  for (std::size_t i = 0; i < got.size(); ++i) {
    SCOPED_TRACE(i);
    expectOdometryEquals(got[i], sent[i], po.frames);
  }
}

TEST_F(DdsPubSub, CustomFramesAndTopicNames) {
  PublisherOptions po = publisherOptions();
  po.topics.odometry = "rt/robot7/odom_";
  po.topics.odometry += std::to_string(::getpid());
  po.frames.world = "odom";
  po.frames.body = "imu_link";
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = po.topics;
  so.pose = false;
  so.status = false;
  Subscriber sub(sub_participant_, so);
  EXPECT_FALSE(sub.subscribed(TopicKind::kPose));
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, kMatchTimeout));
  std::mt19937 rng(22);
  const NavigationState s = testing::randomState(rng, 77'000'000'000);
  ASSERT_TRUE(pub.publishOdometry(s).ok());
  const auto got = receive<OdometryMessage>(sub, 1, [&](auto& out) { sub.takeOdometry(out); });
  ASSERT_EQ(got.size(), 1u);
  expectOdometryEquals(got[0], s, po.frames);
  std::vector<PoseMessage> none;
  EXPECT_EQ(sub.takePose(none), 0u);
}

TEST_F(DdsPubSub, PoseArrivesWithExactFields) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kPose, 1, kMatchTimeout));
  std::mt19937 rng(23);
  const NavigationState s = testing::randomState(rng, 3'500'000'017);
  ASSERT_TRUE(pub.publishPose(s).ok());
  const auto got = receive<PoseMessage>(sub, 1, [&](auto& out) { sub.takePose(out); });
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].stamp_ns, s.t_ns);
  EXPECT_EQ(got[0].source_timestamp_ns, s.t_ns);
  EXPECT_EQ(got[0].frame_id, "map");
  EXPECT_EQ(got[0].p_w_b, s.p_w_b);
  EXPECT_EQ(got[0].q_w_b.coeffs(), s.q_w_b.normalized().coeffs());
  EXPECT_EQ(got[0].covariance, rosPoseCovariance(s));
  std::vector<OdometryMessage> odometry;
  EXPECT_EQ(sub.takeOdometry(odometry), 0u);  // topics do not mix
}

TEST_F(DdsPubSub, StatusArrivesWithExactFields) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kStatus, 1, kMatchTimeout));
  const ServiceStatus s = testing::sampleStatus(9'000'000'000);
  ASSERT_TRUE(pub.publishStatus(s).ok());
  const auto got = receive<StatusMessage>(sub, 1, [&](auto& out) { sub.takeStatus(out); });
  ASSERT_EQ(got.size(), 1u);
  const ServiceStatus& r = got[0].status;
  EXPECT_EQ(got[0].state_name, "degraded");
  EXPECT_EQ(got[0].source_timestamp_ns, s.t_ns);
  EXPECT_EQ(r.t_ns, s.t_ns);
  EXPECT_EQ(r.state, s.state);
  EXPECT_EQ(r.imu_samples, s.imu_samples);
  EXPECT_EQ(r.range_samples, s.range_samples);
  EXPECT_EQ(r.tdoa_samples, s.tdoa_samples);
  EXPECT_EQ(r.ultrasonic_samples, s.ultrasonic_samples);
  EXPECT_EQ(r.queue_overflows, s.queue_overflows);
  EXPECT_EQ(r.late_updates, s.late_updates);
  EXPECT_EQ(r.sensor_faults, s.sensor_faults);
  EXPECT_EQ(r.sensor_silences, s.sensor_silences);
  EXPECT_EQ(r.reinitializations, s.reinitializations);
  EXPECT_EQ(r.rejected_ranges, s.rejected_ranges);
  EXPECT_EQ(r.deep_nlos_tdoa_rows, s.deep_nlos_tdoa_rows);
  EXPECT_EQ(r.published_odometry, s.published_odometry);
  EXPECT_EQ(r.non_finite_samples, s.non_finite_samples);
  EXPECT_EQ(r.duplicate_samples, s.duplicate_samples);
  EXPECT_EQ(r.out_of_order_samples, s.out_of_order_samples);
  EXPECT_EQ(r.imu_gaps, s.imu_gaps);
  EXPECT_EQ(r.ranging_gaps, s.ranging_gaps);
  EXPECT_EQ(r.out_of_bounds_samples, s.out_of_bounds_samples);
  EXPECT_EQ(r.beyond_full_scale_samples, s.beyond_full_scale_samples);
  EXPECT_EQ(r.far_future_samples, s.far_future_samples);
  EXPECT_EQ(r.time_jumps, s.time_jumps);
  EXPECT_EQ(r.last_update_ms, s.last_update_ms);
  EXPECT_EQ(r.mean_update_ms, s.mean_update_ms);
  EXPECT_EQ(r.max_update_ms, s.max_update_ms);
  EXPECT_EQ(r.p99_update_ms, s.p99_update_ms);
  EXPECT_EQ(r.estimator_queue_high_water, s.estimator_queue_high_water);
  EXPECT_EQ(r.publisher_queue_high_water, s.publisher_queue_high_water);
  EXPECT_EQ(r.last_cliques_reeliminated, s.last_cliques_reeliminated);
  EXPECT_EQ(r.last_relinearized, s.last_relinearized);
  EXPECT_EQ(r.last_lambda, s.last_lambda);
  EXPECT_EQ(r.odometry_latency_ms, s.odometry_latency_ms);
  EXPECT_EQ(r.pose_latency_ms, s.pose_latency_ms);
  EXPECT_STREQ(r.last_fault.data(), "dwm3000 /dev/spidev0.0: RX timeout");
  EXPECT_STREQ(r.reason.data(), "no ranging for 12.4 s (IMU only)");
}

TEST_F(DdsPubSub, StatusFaultFillingTheWholeArrayStaysTerminated) {
  Publisher pub(pub_participant_, publisherOptions());
  Subscriber sub(sub_participant_, statusOnly());
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kStatus, 1, kMatchTimeout));
  ServiceStatus s = testing::sampleStatus(1);
  s.last_fault.fill('f');  // no terminating NUL in the source
  s.reason.fill('r');
  s.state = TrackingState::kLost;
  ASSERT_TRUE(pub.publishStatus(s).ok());
  const auto got = receive<StatusMessage>(sub, 1, [&](auto& out) { sub.takeStatus(out); });
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(std::string(got[0].status.last_fault.data()), std::string(127, 'f'));
  EXPECT_EQ(std::string(got[0].status.reason.data()), std::string(s.reason.size() - 1, 'r'));
  EXPECT_EQ(got[0].state_name, "lost");
}

// A subscriber that takes only now and then (a loaded machine, a fast replay)
// still sees every state the service went through, not only the newest.
TEST_F(DdsPubSub, StatusesPublishedBetweenTakesAllArriveInOrder) {
  Publisher pub(pub_participant_, publisherOptions());
  Subscriber sub(sub_participant_, statusOnly());
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kStatus, 1, kMatchTimeout));
  const TrackingState states[] = {TrackingState::kTracking, TrackingState::kDegraded, TrackingState::kDegraded,
                                  TrackingState::kTracking, TrackingState::kLost};
  for (std::size_t i = 0; i < std::size(states); ++i) {
    ServiceStatus s = testing::sampleStatus(static_cast<std::int64_t>(i + 1) * 1'000);
    s.state = states[i];
    ASSERT_TRUE(pub.publishStatus(s).ok());
  }
  // Reliable on loopback: wait for the newest, then nothing may be missing.
  std::vector<StatusMessage> got;
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while ((got.empty() || got.back().status.t_ns != 5'000) && std::chrono::steady_clock::now() < deadline) {
    if (sub.waitForData(100ms)) sub.takeStatus(got);
  }
  ASSERT_EQ(got.size(), std::size(states));
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].status.t_ns, static_cast<std::int64_t>(i + 1) * 1'000) << "status " << i;
    EXPECT_EQ(got[i].status.state, states[i]) << "status " << i;
  }
}

// A status lost on the wire is repaired itself, not replaced by the newest:
// the writer keeps the last kStatusWriterDepth until acknowledged, yet
// serves late joiners only the newest (the test below).
TEST(DdsQos, StatusWriterKeepsUnacknowledgedStatusesForRepair) {
  const QosPtr qos = writerQos(TopicKind::kStatus);
  dds_history_kind_t kind{};
  std::int32_t depth = 0;
  ASSERT_TRUE(dds_qget_history(qos.get(), &kind, &depth));
  EXPECT_EQ(kind, DDS_HISTORY_KEEP_LAST);
  EXPECT_EQ(depth, kStatusWriterDepth);
  dds_duration_t cleanup = 0;
  dds_history_kind_t late_kind{};
  std::int32_t late_depth = 0, max_samples = 0, max_instances = 0, max_per_instance = 0;
  ASSERT_TRUE(dds_qget_durability_service(qos.get(), &cleanup, &late_kind, &late_depth, &max_samples, &max_instances,
                                          &max_per_instance));
  EXPECT_EQ(late_kind, DDS_HISTORY_KEEP_LAST);
  EXPECT_EQ(late_depth, 1);
  dds_reliability_kind_t reliability{};
  dds_duration_t blocking = 1;
  ASSERT_TRUE(dds_qget_reliability(qos.get(), &reliability, &blocking));
  EXPECT_EQ(reliability, DDS_RELIABILITY_RELIABLE);
  EXPECT_EQ(blocking, 0) << "a congested link must not stall the status thread";
}

// Transient-local: a listener that joins after the last status still gets it.
TEST_F(DdsPubSub, LateStatusSubscriberGetsTheLastStatus) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  ServiceStatus first = testing::sampleStatus(1'000);
  first.state = TrackingState::kInitializing;
  ASSERT_TRUE(pub.publishStatus(first).ok());
  const ServiceStatus last = testing::sampleStatus(2'000);
  ASSERT_TRUE(pub.publishStatus(last).ok());

  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  const auto got = receive<StatusMessage>(sub, 1, [&](auto& out) { sub.takeStatus(out); });
  ASSERT_EQ(got.size(), 1u);  // the writer keeps only the newest for late joiners
  EXPECT_EQ(got[0].status.t_ns, last.t_ns);
  EXPECT_EQ(got[0].state_name, "degraded");
}

TEST_F(DdsPubSub, WaitForDataTimesOutWithoutPublisher) {
  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  EXPECT_FALSE(sub.waitForData(50ms));
  EXPECT_EQ(sub.matchedPublishers(TopicKind::kOdometry), 0u);
  EXPECT_FALSE(sub.waitForPublishers(TopicKind::kPose, 1, 50ms));
}

TEST_F(DdsPubSub, InvalidStatesAreRejectedWithoutWriting) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = names_;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, kMatchTimeout));
  std::mt19937 rng(24);
  NavigationState s = testing::randomState(rng, 1'000);
  s.valid = false;
  WriteStatus ws = pub.publishOdometry(s);
  EXPECT_EQ(ws.code, DDS_RETCODE_PRECONDITION_NOT_MET);
  EXPECT_STREQ(ws.text(), "navigation state not valid (estimator not initialized)");
  s.valid = true;
  s.t_ns = -5;
  ws = pub.publishPose(s);
  EXPECT_EQ(ws.code, DDS_RETCODE_BAD_PARAMETER);
  EXPECT_STREQ(ws.text(), "negative t_ns");
  s.t_ns = 5;
  s.p_w_b.x() = std::numeric_limits<double>::quiet_NaN();
  ws = pub.publishOdometry(s);
  EXPECT_EQ(ws.code, DDS_RETCODE_BAD_PARAMETER);
  EXPECT_STREQ(ws.text(), "non-finite navigation state");
  EXPECT_FALSE(sub.waitForData(100ms));
  EXPECT_STREQ(WriteStatus{}.text(), dds_strretcode(DDS_RETCODE_OK));
}

// ROS 2 stamps are system time: the publisher adds its tracked offset to the
// samples' CLOCK_MONOTONIC t_ns; the status keeps rilo's time too.
TEST_F(DdsPubSub, SystemStampsAreTheSampleTimePlusTheTrackedOffset) {
  PublisherOptions po = publisherOptions();
  po.stamp_clock = StampClock::kSystem;
  Publisher pub(pub_participant_, po);
  SubscriberOptions so;
  so.topics = names_;
  so.tf = true;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, kMatchTimeout));
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kTf, 1, kMatchTimeout));
  timespec mono{}, real{};
  clock_gettime(CLOCK_MONOTONIC, &mono);
  std::mt19937 rng(25);
  const NavigationState s = testing::randomState(rng, mono.tv_sec * 1'000'000'000LL + mono.tv_nsec);
  const std::int64_t offset_ns = pub.stampOffsetNs();
  ASSERT_TRUE(pub.publishOdometry(s).ok());
  ASSERT_TRUE(pub.publishPose(s).ok());
  ASSERT_TRUE(pub.publishTransform(s).ok());
  ServiceStatus status = testing::sampleStatus(s.t_ns);
  ASSERT_TRUE(pub.publishStatus(status).ok());
  const auto odometry = receive<OdometryMessage>(sub, 1, [&](auto& out) { sub.takeOdometry(out); });
  const auto pose = receive<PoseMessage>(sub, 1, [&](auto& out) { sub.takePose(out); });
  const auto tf = receive<TfMessage>(sub, 1, [&](auto& out) { sub.takeTf(out); });
  const auto got_status = receive<StatusMessage>(sub, 1, [&](auto& out) { sub.takeStatus(out); });
  clock_gettime(CLOCK_REALTIME, &real);
  ASSERT_EQ(odometry.size(), 1u);
  ASSERT_EQ(pose.size(), 1u);
  ASSERT_EQ(tf.size(), 1u);
  ASSERT_EQ(tf[0].transforms.size(), 1u);
  ASSERT_EQ(got_status.size(), 1u);
  EXPECT_EQ(odometry[0].stamp_ns, s.t_ns + offset_ns);
  EXPECT_EQ(odometry[0].source_timestamp_ns, s.t_ns + offset_ns);
  EXPECT_EQ(pose[0].stamp_ns, s.t_ns + offset_ns);
  EXPECT_EQ(tf[0].transforms[0].stamp_ns, s.t_ns + offset_ns);
  EXPECT_EQ(got_status[0].stamp_ns, s.t_ns + offset_ns);
  EXPECT_EQ(got_status[0].status.t_ns, s.t_ns) << "monotonic_ns: the same instant on rilo's clock";
  // The stamp is the wall clock of the moment the state was taken (CLOCK_MONOTONIC
  // and CLOCK_REALTIME are decades apart on any machine; 60 s allows a loaded one).
  const std::int64_t real_ns = real.tv_sec * 1'000'000'000LL + real.tv_nsec;
  EXPECT_LT(std::llabs(real_ns - odometry[0].stamp_ns), 60'000'000'000LL);
}

TEST_F(DdsPubSub, MonotonicStampsAddNothing) {
  Publisher pub(pub_participant_, publisherOptions());
  pub.refreshStampOffset();
  EXPECT_EQ(pub.stampOffsetNs(), 0);
}

// TF (rviz2 needs it): the odometry's pose as map -> base_link, same stamp.
TEST_F(DdsPubSub, TfCarriesTheOdometryPoseUnderTheConfiguredFrames) {
  PublisherOptions po = publisherOptions();
  po.frames.world = "world_" + std::to_string(::getpid());
  po.frames.body = "tag_link";
  Publisher pub(pub_participant_, po);
  EXPECT_TRUE(pub.publishesTf());
  SubscriberOptions so;
  so.topics = names_;
  so.pose = false;
  so.status = false;
  so.tf = true;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kTf, 1, kMatchTimeout));
  ASSERT_TRUE(sub.waitForPublishers(TopicKind::kTf, 1, kMatchTimeout));
  std::mt19937 rng(26);
  std::vector<NavigationState> sent;
  for (int i = 0; i < 10; ++i) {
    sent.push_back(testing::randomState(rng, 20'000'000'000 + i * 5'000'000));
    ASSERT_TRUE(pub.publishOdometry(sent.back()).ok());
    const WriteStatus ws = pub.publishTransform(sent.back());
    ASSERT_TRUE(ws.ok()) << ws.text();
  }
  const auto odometry = receive<OdometryMessage>(sub, sent.size(), [&](auto& out) { sub.takeOdometry(out); });
  const auto tf = receive<TfMessage>(sub, sent.size(), [&](auto& out) { sub.takeTf(out); });
  ASSERT_EQ(odometry.size(), sent.size());
  ASSERT_EQ(tf.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    SCOPED_TRACE(i);
    ASSERT_EQ(tf[i].transforms.size(), 1u);
    const TransformMessage& t = tf[i].transforms[0];
    EXPECT_EQ(t.stamp_ns, odometry[i].stamp_ns);
    EXPECT_EQ(tf[i].source_timestamp_ns, odometry[i].source_timestamp_ns);
    EXPECT_EQ(t.frame_id, odometry[i].frame_id);
    EXPECT_EQ(t.child_frame_id, odometry[i].child_frame_id);
    EXPECT_EQ(t.frame_id, po.frames.world);
    EXPECT_EQ(t.child_frame_id, "tag_link");
    EXPECT_EQ(t.translation, odometry[i].p_w_b);
    EXPECT_EQ(t.rotation.coeffs(), odometry[i].q_w_b.coeffs());
  }
}

// rt/rilo/ranges: a ranging epoch's ranges as the estimator judged them.
TEST_F(DdsPubSub, RangesArriveWithEveryReadingUpToTheCapacity) {
  PublisherOptions po = publisherOptions();
  Publisher pub(pub_participant_, po);
  EXPECT_TRUE(pub.publishesRanges());
  SubscriberOptions so;
  so.topics = names_;
  so.odometry = so.pose = so.status = false;
  so.ranges = true;
  Subscriber sub(sub_participant_, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kRanges, 1, kMatchTimeout));
  const std::vector<RangeReading> epoch{{0, 4.25, 4.2, 0.05, 0.98, false, 0}, {3, 7.9, 6.1, 1.8, 0.02, true, 37'500'000}};
  ASSERT_TRUE(pub.publishRanges(12'000'000'000, epoch).ok());
  std::vector<RangeReading> many(Publisher::kMaxRanges + 5, RangeReading{5, 1.0, 1.0, 0.0, 1.0, false});
  ASSERT_TRUE(pub.publishRanges(12'025'000'000, many).ok());
  EXPECT_EQ(pub.publishRanges(-1, epoch).code, DDS_RETCODE_BAD_PARAMETER);
  const auto got = receive<RangesMessage>(sub, 2, [&](auto& out) { sub.takeRanges(out); });
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[0].stamp_ns, 12'000'000'000);
  EXPECT_EQ(got[0].frame_id, "map");
  ASSERT_EQ(got[0].ranges.size(), 2u);
  EXPECT_EQ(got[0].ranges[1].anchor_id, 3u);
  EXPECT_EQ(got[0].ranges[1].range_m, 7.9);
  EXPECT_EQ(got[0].ranges[1].predicted_m, 6.1);
  EXPECT_EQ(got[0].ranges[1].residual_m, 1.8);
  EXPECT_EQ(got[0].ranges[1].weight, 0.02);
  EXPECT_TRUE(got[0].ranges[1].nlos);
  EXPECT_FALSE(got[0].ranges[0].nlos);
  EXPECT_EQ(got[0].ranges[0].t_offset_ns, 0);
  EXPECT_EQ(got[0].ranges[1].t_offset_ns, 37'500'000) << "each range's own time after the state's stamp";
  EXPECT_EQ(got[1].ranges.size(), Publisher::kMaxRanges) << "the first kMaxRanges of an epoch";
}

TEST_F(DdsPubSub, AnEmptyTfTopicNamePublishesNoTf) {
  PublisherOptions po = publisherOptions();
  po.topics.tf.clear();
  Publisher pub(pub_participant_, po);
  EXPECT_FALSE(pub.publishesTf());
  EXPECT_EQ(pub.matchedSubscribers(TopicKind::kTf), 0u);
  std::mt19937 rng(27);
  EXPECT_TRUE(pub.publishTransform(testing::randomState(rng, 1'000)).ok());
  SubscriberOptions so;
  so.topics = po.topics;
  so.tf = true;
  EXPECT_THROW(Subscriber(sub_participant_, so), std::invalid_argument);
}

}  // namespace
}  // namespace rilo::dds
