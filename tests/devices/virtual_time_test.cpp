#include "devices/emulation/virtual_time.h"

#include <gtest/gtest.h>

#include <vector>

namespace rilo::emu {
namespace {

TEST(VirtualClock, RunsEventsInTimeOrderAndEachSeesItsOwnTime) {
  VirtualClock clock(0);
  std::vector<std::int64_t> seen;
  clock.schedule(300, [&] { seen.push_back(clock.nowNs()); });
  clock.schedule(100, [&] {
    seen.push_back(clock.nowNs());
    clock.schedule(200, [&] { seen.push_back(clock.nowNs()); });  // scheduled from an event
  });
  clock.sleepForNs(250);
  EXPECT_EQ(seen, (std::vector<std::int64_t>{100, 200}));
  EXPECT_EQ(clock.nowNs(), 250);
  clock.advanceTo(1000);
  EXPECT_EQ(seen, (std::vector<std::int64_t>{100, 200, 300}));
  EXPECT_EQ(clock.pendingEvents(), 0u);
}

TEST(EmulatedInterruptLine, WaitAdvancesToTheDeviceEventOrTimesOut) {
  VirtualClock clock(0);
  EmulatedInterruptLine irq(clock, "emu:irq");
  clock.schedule(5'000, [&] { irq.setLevel(true); });
  hal::EdgeEvent event;
  std::error_code error;
  EXPECT_EQ(irq.waitEdge(std::chrono::microseconds(2), event, error), hal::WaitResult::kTimeout);
  EXPECT_EQ(clock.nowNs(), 2'000);
  ASSERT_EQ(irq.waitEdge(std::chrono::microseconds(10), event, error), hal::WaitResult::kEdge);
  EXPECT_EQ(event.t_ns, 5'000);
  // Level still high: no new edge until it drops and rises again.
  EXPECT_EQ(irq.waitEdge(std::chrono::microseconds(10), event, error), hal::WaitResult::kTimeout);
  irq.setLevel(false);
  irq.setLevel(true);
  EXPECT_EQ(irq.waitEdge(std::chrono::microseconds(10), event, error), hal::WaitResult::kEdge);
}

TEST(EmulatedInterruptLine, InjectedFailureAndJitter) {
  VirtualClock clock(0);
  EmulatedInterruptLine irq(clock, "emu:irq");
  irq.failNextWaits(1, std::make_error_code(std::errc::io_error));
  hal::EdgeEvent event;
  std::error_code error;
  EXPECT_EQ(irq.waitEdge(std::chrono::microseconds(1), event, error), hal::WaitResult::kError);
  EXPECT_EQ(error, std::make_error_code(std::errc::io_error));
  irq.setTimestampJitter([] { return std::int64_t{700}; });
  irq.setLevel(true);
  ASSERT_EQ(irq.waitEdge(std::chrono::microseconds(1), event, error), hal::WaitResult::kEdge);
  EXPECT_EQ(event.t_ns, 700);
  EXPECT_EQ(clock.nowNs(), 700);
}

}  // namespace
}  // namespace rilo::emu
