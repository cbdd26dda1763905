// A status subscriber that stalls while odometry floods its socket (a loaded
// machine: the kernel drops what its full receive buffer cannot hold) still
// gets every status, in order, once it runs again: the status writer keeps
// the unacknowledged ones and repairs each, not only the newest (qos.h).
//
// The subscriber is this binary re-executed with RILO_DDS_STALLED_READER_DOMAIN
// set (it runs before main() and exits); the test stops it with SIGSTOP,
// publishes, and continues it.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "dds/publisher.h"
#include "dds/subscriber.h"
#include "dds_test_support.h"
#include "support/child_process.h"

namespace rilo::dds {
namespace {

using namespace std::chrono_literals;

constexpr int kStatusCount = 12;
constexpr int kOdometryPerStatus = 800;  // ~0.5 MB between two statuses: more than a socket buffer holds
constexpr std::int64_t kStatusPeriodNs = 1'000'000;

std::int64_t statusStamp(int i) { return (i + 1) * kStatusPeriodNs; }

TopicNames namesFromEnvironment() {
  TopicNames names;
  names.odometry = std::getenv("RILO_DDS_STALLED_READER_ODOMETRY");
  names.status = std::getenv("RILO_DDS_STALLED_READER_STATUS");
  return names;
}

/// The stalled subscriber: exits 0 when it received exactly the statuses
/// published, in order; prints what it got otherwise.
int runStalledReader(std::uint32_t domain_id) {
  try {
    Participant participant(testing::loopbackOptions(domain_id));
    SubscriberOptions so;
    so.topics = namesFromEnvironment();
    so.pose = false;
    Subscriber sub(participant, so);
    std::vector<OdometryMessage> odometry;
    std::vector<StatusMessage> status;
    std::size_t odometry_count = 0;
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (std::chrono::steady_clock::now() < deadline &&
           (status.empty() || status.back().status.t_ns != statusStamp(kStatusCount - 1))) {
      if (sub.waitForData(50ms)) {
        odometry.clear();
        odometry_count += sub.takeOdometry(odometry);
        sub.takeStatus(status);
      }
    }
    // Informational: on a host whose socket buffers hold the whole flood
    // nothing is lost and the test does not exercise the repair.
    std::printf("[ stalled  ] %zu of %d best-effort odometry samples reached the stopped reader\n", odometry_count,
                kStatusCount * kOdometryPerStatus);
    std::fflush(stdout);
    bool exact = status.size() == static_cast<std::size_t>(kStatusCount);
    for (std::size_t i = 0; exact && i < status.size(); ++i) exact = status[i].status.t_ns == statusStamp(static_cast<int>(i));
    if (exact) return 0;
    std::fprintf(stderr, "stalled reader: %zu of %d statuses, stamps (ms):", status.size(), kStatusCount);
    for (const StatusMessage& m : status) std::fprintf(stderr, " %lld", static_cast<long long>(m.status.t_ns / 1'000'000));
    std::fprintf(stderr, "\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stalled reader: %s\n", e.what());
    return 2;
  }
}

// Runs during static initialization of the re-executed binary only.
const bool g_is_stalled_reader = [] {
  const char* domain = std::getenv("RILO_DDS_STALLED_READER_DOMAIN");
  if (domain == nullptr) return false;
  std::exit(runStalledReader(static_cast<std::uint32_t>(std::stoul(domain))));
}();

pid_t spawnReader(std::uint32_t domain_id, const TopicNames& names) {
  return testing::spawnSelf({"RILO_DDS_STALLED_READER_DOMAIN=" + std::to_string(domain_id),
                             "RILO_DDS_STALLED_READER_ODOMETRY=" + names.odometry,
                             "RILO_DDS_STALLED_READER_STATUS=" + names.status});
}

/// Continues, kills and reaps the child unless it was reaped: a failed
/// assertion between SIGSTOP and SIGCONT must not leave it stopped.
struct ChildGuard {
  pid_t pid;
  bool reaped = false;
  ~ChildGuard() {
    if (pid <= 0 || reaped) return;
    kill(pid, SIGCONT);
    kill(pid, SIGKILL);
    waitpid(pid, nullptr, 0);
  }
};

TEST(DdsStatusRepair, AStalledSubscriberGetsEveryStatusPublishedWhileOdometryFloodedIt) {
  ASSERT_FALSE(g_is_stalled_reader);
  const std::uint32_t domain_id = testing::uniqueDomainId();
  TopicNames names = testing::uniqueTopicNames("status_repair");
  Participant participant(testing::loopbackOptions(domain_id));
  PublisherOptions po;
  po.topics = names;
  po.topics.tf.clear();
  po.stamp_clock = StampClock::kMonotonic;
  Publisher pub(participant, po);

  ChildGuard reader{spawnReader(domain_id, names)};
  ASSERT_GT(reader.pid, 0) << "posix_spawn failed";
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kOdometry, 1, testing::kMatchTimeout));
  ASSERT_TRUE(pub.waitForSubscribers(TopicKind::kStatus, 1, testing::kMatchTimeout));
  std::this_thread::sleep_for(300ms);  // the reader side accepts this writer too

  // Stopped for well under Cyclone's 10 s lease: the writer keeps the reader.
  ASSERT_EQ(kill(reader.pid, SIGSTOP), 0);
  std::mt19937 rng(7);
  NavigationState state = testing::randomState(rng, 0);
  bool all_written = true;
  for (int i = 0; i < kStatusCount; ++i) {
    for (int k = 0; k < kOdometryPerStatus; ++k) {
      state.t_ns += 1'000;
      (void)pub.publishOdometry(state);  // best effort: most are dropped by the stopped reader's kernel
    }
    all_written = pub.publishStatus(testing::sampleStatus(statusStamp(i))).ok() && all_written;
  }
  ASSERT_EQ(kill(reader.pid, SIGCONT), 0);
  ASSERT_TRUE(all_written) << "a status write failed (DDS_RETCODE_TIMEOUT: too much unacknowledged, qos.h)";
  EXPECT_TRUE(pub.waitForAcknowledgments(30s)) << "the reader acknowledged every status";
  const int code = rilo::testing::waitExit(reader.pid, 60s);  // -1: killed at the timeout
  reader.reaped = true;
  ASSERT_NE(code, -1) << "the stalled reader did not finish";
  EXPECT_EQ(code, 0) << "the stalled reader missed or reordered statuses (see its stderr)";
}

}  // namespace
}  // namespace rilo::dds
