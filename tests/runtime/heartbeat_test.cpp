#include "runtime/heartbeat.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdint>
#include <thread>

#include "runtime/runtime_counters.h"

namespace rilo {
namespace {

constexpr std::int64_t kMs = 1'000'000;

TEST(Heartbeat, NotAliveBeforeFirstBeat) {
  const Heartbeat hb;
  EXPECT_FALSE(hb.isAlive(0, 1000 * kMs));
  EXPECT_FALSE(hb.isAlive(5 * kMs, 1000 * kMs));
  EXPECT_EQ(hb.count(), 0u);
}

TEST(Heartbeat, AliveWithinMaxAgeOnly) {
  Heartbeat hb;
  hb.beat(100 * kMs);
  EXPECT_EQ(hb.count(), 1u);
  EXPECT_EQ(hb.lastBeatNs(), 100 * kMs);
  EXPECT_TRUE(hb.isAlive(100 * kMs, 50 * kMs));
  EXPECT_TRUE(hb.isAlive(150 * kMs, 50 * kMs));   // exactly max age
  EXPECT_FALSE(hb.isAlive(151 * kMs, 50 * kMs));
  EXPECT_TRUE(hb.isAlive(90 * kMs, 50 * kMs));    // watchdog read its clock before the beat
  hb.beat(200 * kMs);
  EXPECT_TRUE(hb.isAlive(240 * kMs, 50 * kMs));
  EXPECT_EQ(hb.count(), 2u);
}

// A loop beating while a watchdog watches: the watchdog sees it alive while it
// runs (its clock never gets ahead of the loop by more than max age here) and
// dead once it stops.
TEST(Heartbeat, WatchdogSeesLoopFromAnotherThread) {
  Heartbeat hb;
  std::atomic<std::int64_t> clock_ns{0};
  std::atomic<bool> stop{false};
  std::thread loop([&] {
    for (int i = 1; i <= 200'000; ++i) {
      const std::int64_t now = clock_ns.fetch_add(kMs) + kMs;
      hb.beat(now);
    }
    stop.store(true);
  });
  std::uint64_t dead_while_running = 0;
  while (!stop.load()) {
    // The loop has beaten at least at this time minus one period once count > 0.
    const std::int64_t now = clock_ns.load();
    if (hb.count() > 0 && !hb.isAlive(now, 2 * kMs)) ++dead_while_running;
  }
  loop.join();
  EXPECT_EQ(dead_while_running, 0u);
  EXPECT_EQ(hb.count(), 200'000u);
  EXPECT_FALSE(hb.isAlive(clock_ns.load() + 3 * kMs, 2 * kMs));
}

TEST(RuntimeCounters, FillCopiesEveryCounter) {
  RuntimeCounters c;
  c.imu_samples.add(10);
  c.range_samples.add(4);
  c.queue_overflows.add();
  c.late_updates.add(2);
  c.sensor_faults.add(3);
  c.sensor_silences.add(5);
  c.reinitializations.add(6);
  c.rejected_ranges.add(7);
  c.deep_nlos_tdoa_rows.add(11);
  c.tdoa_samples.add(12);
  c.ultrasonic_samples.add(13);
  c.published_odometry.add(8);
  ServiceStatus s;
  s.max_update_ms = 9.5;
  c.fill(s);
  EXPECT_EQ(s.imu_samples, 10u);
  EXPECT_EQ(s.range_samples, 4u);
  EXPECT_EQ(s.queue_overflows, 1u);
  EXPECT_EQ(s.late_updates, 2u);
  EXPECT_EQ(s.sensor_faults, 3u);
  EXPECT_EQ(s.sensor_silences, 5u);
  EXPECT_EQ(s.reinitializations, 6u);
  EXPECT_EQ(s.rejected_ranges, 7u);
  EXPECT_EQ(s.deep_nlos_tdoa_rows, 11u);
  EXPECT_EQ(s.tdoa_samples, 12u);
  EXPECT_EQ(s.ultrasonic_samples, 13u);
  EXPECT_EQ(s.published_odometry, 8u);
  EXPECT_EQ(s.max_update_ms, 9.5);  // untouched
}

TEST(RuntimeCounters, ConcurrentAddsAreNotLost) {
  RuntimeCounters c;
  std::thread a([&] {
    for (int i = 0; i < 100'000; ++i) c.queue_overflows.add();
  });
  std::thread b([&] {
    for (int i = 0; i < 100'000; ++i) c.queue_overflows.add();
  });
  a.join();
  b.join();
  EXPECT_EQ(c.queue_overflows.load(), 200'000u);
  EXPECT_EQ(alignof(EventCounter), kCacheLineBytes);
}

}  // namespace
}  // namespace rilo
