// The assembled service's IMU-rate path neither allocates nor locks. rilod's Service is
// built in-process from a configuration exactly as the daemon builds it
// (serviceOptions, makeReplaySource), replays the office recording as fast as
// possible, and publishes over real Cyclone DDS (loopback). Its source thread
// (replay -> entrance screen -> queues -> counters) and its publisher thread
// (queue -> seqlock hand-over -> output predictor -> DDS odometry write) count
// their heap allocations and lock acquisitions after warm-up (tracking, 2000
// odometry messages written), for 8000 more IMU samples.
//
// Asserted: zero allocations and zero locks in rilo's code on both threads. Cyclone's
// dds_write_ts is counted apart (support/thread_activity.h) and printed: its one
// malloc + one realloc per write (the serialized sample, from glibc's
// per-thread cache) are Cyclone's, measured in tests/dds too; the test only
// bounds them so that a change in how rilo drives Cyclone (e.g. an
// unregistered instance: +2.5 per write) shows.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

#include "rilod/config.h"
#include "rilod/service.h"
#include "rilod/service_setup.h"
#include "rilod_runner.h"
#include "service/support/thread_activity.h"
#include "service_test_support.h"

namespace rilo {
namespace {

using namespace std::chrono_literals;

TEST(ImuRatePath, AssembledServiceNeitherAllocatesNorLocksPerImuSampleOutsideCyclone) {
  testing::TempDir dir("rilod-alloc");
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  const ServiceConfig cfg = parseServiceConfig(
      "sources:\n  mode: replay\n  replay:\n    path: " + rec +
          "\n    pace: as_fast_as_possible\n    shift_to_now: false\n"
          "anchors:\n  file: " + rec + "/anchors.csv\n"
          "estimator:\n  smoother: d-isam2\n  range:\n    lever_arm_m: [0.06, 0.0, 0.10]\n"
          "dds:\n  domain: " + std::to_string(testing::testDomain()) + "\n  loopback_only: true\n"
          "realtime:\n  lock_memory: false\n  queue_capacity: 1024\n"
          "status:\n  period_s: 0.02\n",
      dir / "rilod.yaml");

  // The estimator is enrolled as the control: it allocates by design (the
  // smoother's graph), so its count proves the counter sees the service's threads.
  testing::ThreadActivity source_counts, publisher_counts, estimator_counts;
  ServiceOptions options = serviceOptions(cfg);
  options.on_thread_enter = [&](const char* role) {
    if (std::strcmp(role, "publisher") == 0) testing::enrollThisThread(publisher_counts);
    if (std::strncmp(role, "source", 6) == 0) testing::enrollThisThread(source_counts);
    if (std::strcmp(role, "estimator") == 0) testing::enrollThisThread(estimator_counts);
  };
  std::vector<std::unique_ptr<SampleSource>> sources;
  sources.push_back(makeReplaySource(cfg.sources.replay));
  Service service(std::move(options), std::move(sources));

  std::atomic<bool> stop{false};
  int code = -1;
  std::thread runner([&] { code = service.run(stop); });
  auto waitFor = [&](auto done) {
    const auto end = std::chrono::steady_clock::now() +
                     std::chrono::duration_cast<std::chrono::steady_clock::duration>(120s * testing::timeScale());
    while (!done(service.status()) && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(1ms);
    return done(service.status());
  };

  // Warm-up: queues, caches, the predictor's ring and Cyclone's writer settle.
  const bool warm = waitFor([](const ServiceStatus& s) {
    return s.state == TrackingState::kTracking && s.published_odometry >= 2000;
  });
  testing::armThreadCounting(true);
  const std::uint64_t armed_at = service.status().published_odometry;
  const std::uint64_t imu_at = service.status().imu_samples;
  const bool measured = waitFor([&](const ServiceStatus& s) { return s.published_odometry >= armed_at + 8000; });
  testing::armThreadCounting(false);
  const ServiceStatus end_status = service.status();
  stop.store(true);
  runner.join();
  ASSERT_TRUE(warm) << "never tracked";
  ASSERT_TRUE(measured) << "the replay ended before 8000 odometry messages were counted";
  EXPECT_EQ(code, 0);

  auto u = [](const std::atomic<std::uint64_t>& v) { return static_cast<unsigned long long>(v.load()); };
  const std::uint64_t writes = publisher_counts.dds_writes.load();
  const double per_write = writes > 0 ? 1.0 / static_cast<double>(writes) : 0.0;
  std::printf(
      "IMU-rate path after warm-up: %llu IMU samples in, %llu DDS writes (odometry and TF)\n"
      "  source thread:    %llu allocations, %llu locks\n"
      "  publisher thread: %llu allocations, %llu locks in rilo's code; inside dds_write_ts (Cyclone) %llu allocations "
      "(%.2f per write), %llu locks (%.2f per write)\n"
      "  control, estimator thread: %llu allocations, %llu locks%s\n"
      "  updates p99 %.2f ms, max %.2f ms; queues' high water %u (estimator) / %u (publisher) of 1024\n",
      static_cast<unsigned long long>(end_status.imu_samples - imu_at), static_cast<unsigned long long>(writes),
      u(source_counts.allocations), u(source_counts.locks), u(publisher_counts.allocations), u(publisher_counts.locks),
      u(publisher_counts.cyclone_allocations), static_cast<double>(publisher_counts.cyclone_allocations.load()) * per_write,
      u(publisher_counts.cyclone_locks), static_cast<double>(publisher_counts.cyclone_locks.load()) * per_write,
      u(estimator_counts.allocations), u(estimator_counts.locks),
      testing::countsMallocAndLocks() ? "" : " [sanitizer build: operator new only, locks not counted]",
      end_status.p99_update_ms, end_status.max_update_ms, end_status.estimator_queue_high_water,
      end_status.publisher_queue_high_water);
  // The budget figures a bring-up reads from the status topic: a replay as
  // fast as possible fills the 1024-slot queues, so the consumers saw them fill.
  EXPECT_GT(end_status.p99_update_ms, 0.0);
  EXPECT_LE(end_status.p99_update_ms, end_status.max_update_ms * 1.11) << "one histogram bucket above the slowest";
  EXPECT_GE(end_status.estimator_queue_high_water, 1u);
  EXPECT_LE(end_status.estimator_queue_high_water, 1024u);
  EXPECT_GE(end_status.publisher_queue_high_water, 1u);
  EXPECT_LE(end_status.publisher_queue_high_water, 1024u);
  EXPECT_GT(estimator_counts.allocations.load(), 1000u) << "the counter sees the service's threads";
  EXPECT_GE(writes, 7500u);  // the status counter and the write count are read at slightly different times
  EXPECT_GE(end_status.imu_samples - imu_at, 7500u);
  EXPECT_EQ(source_counts.allocations.load(), 0u) << "replay, entrance screen, queues, counters";
  EXPECT_EQ(publisher_counts.allocations.load(), 0u) << "queue, hand-over, output predictor, odometry fill";
  EXPECT_EQ(source_counts.cyclone_allocations.load() + source_counts.dds_writes.load(), 0u);
  if (testing::countsMallocAndLocks()) {
    EXPECT_GT(estimator_counts.locks.load(), 0u) << "the lock counter sees the service's threads (stats mutex)";
    EXPECT_EQ(source_counts.locks.load(), 0u);
    EXPECT_EQ(publisher_counts.locks.load(), 0u);
    EXPECT_LE(publisher_counts.cyclone_allocations.load(), 2 * writes + 64)
        << "Cyclone's write: 1 malloc + 1 realloc per sample expected";
  }
}

}  // namespace
}  // namespace rilo
