// Cost of one odometry write, printed for the record (no timing assertions:
// the machine is shared). See also the cross-process figure printed by
// cross_process_test.cpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "dds/conversions.h"
#include "dds/publisher.h"
#include "dds/subscriber.h"
#include "dds_test_support.h"

namespace rilo::dds {
namespace {

constexpr int kWrites = 20000;

void measure(Publisher& pub, const char* what) {
  std::mt19937 rng(41);
  NavigationState state = testing::randomState(rng, 1'000'000'000);
  for (int i = 0; i < 1000; ++i) {
    state.t_ns += 5'000'000;
    ASSERT_TRUE(pub.publishOdometry(state).ok());
  }
  std::vector<double> batch_ns;  // per-write mean over batches of 100, robust to preemption
  for (int b = 0; b < kWrites / 100; ++b) {
    const auto start = std::chrono::steady_clock::now();
    bool ok = true;
    for (int i = 0; i < 100; ++i) {
      state.t_ns += 5'000'000;
      ok = pub.publishOdometry(state).ok() && ok;
    }
    batch_ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() /
                       100.0);
    ASSERT_TRUE(ok);
  }
  std::sort(batch_ns.begin(), batch_ns.end());
  std::printf("[ cost     ] odometry write, %s: median %.0f ns, p90 %.0f ns (batches of 100, %d writes)\n", what,
              batch_ns[batch_ns.size() / 2], batch_ns[batch_ns.size() * 9 / 10], kWrites);
}

TEST(DdsWriteCost, OdometryConversionOnly) {
  std::mt19937 rng(42);
  NavigationState state = testing::randomState(rng, 1'000'000'000);
  nav_msgs_msg_dds__Odometry_ msg{};
  const auto start = std::chrono::steady_clock::now();
  double sink = 0.0;
  for (int i = 0; i < kWrites; ++i) {
    state.t_ns += 5'000'000;
    fillOdometry(state, msg);
    sink += msg.twist.covariance[7];
  }
  const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count();
  std::printf("[ cost     ] fillOdometry (our conversion): %.0f ns per sample (%d samples)\n", ns / kWrites, kWrites);
  EXPECT_TRUE(std::isfinite(sink));
}

TEST(DdsWriteCost, OdometryWithoutSubscriber) {
  Participant participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("cost_nosub");
  Publisher pub(participant, po);
  measure(pub, "no subscriber");
}

TEST(DdsWriteCost, OdometryWithInProcessSubscriber) {
  Participant pub_participant(testing::loopbackOptions());
  Participant sub_participant(testing::loopbackOptions());
  PublisherOptions po;
  po.topics = testing::uniqueTopicNames("cost_sub");
  Publisher pub(pub_participant, po);
  SubscriberOptions so;
  so.topics = po.topics;
  so.odometry_depth = 1;
  Subscriber sub(sub_participant, so);
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, testing::kMatchTimeout));
  measure(pub, "in-process subscriber");
}

}  // namespace
}  // namespace rilo::dds
