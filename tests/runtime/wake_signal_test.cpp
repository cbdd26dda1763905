// WakeSignal: a notify() is never lost, whether it comes before the wait, while
// the consumer sleeps, or between the consumer's last look and its sleep. The
// checks that involve time only ask "did wait() run into its (long) timeout",
// never how fast anything was.
#include "runtime/wake_signal.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <thread>

#include "runtime/spsc_queue.h"

namespace rilo {
namespace {

using Clock = std::chrono::steady_clock;
constexpr std::int64_t kLongTimeoutNs = 5'000'000'000;

bool ranIntoTimeout(Clock::time_point start) {
  return Clock::now() - start >= std::chrono::nanoseconds(kLongTimeoutNs);
}

TEST(WakeSignal, NotifyWithoutAWaiterOnlyCounts) {
  WakeSignal w;
  for (int i = 0; i < 1000; ++i) w.notify();
  EXPECT_EQ(w.events(), 1000u);
}

TEST(WakeSignal, ANotifyAfterPrepareWaitMakesTheWaitReturnAtOnce) {
  WakeSignal w;
  const std::uint32_t token = w.prepareWait();
  w.notify();  // e.g. the producer pushed after the consumer's last look
  const auto start = Clock::now();
  w.wait(token, kLongTimeoutNs);
  EXPECT_FALSE(ranIntoTimeout(start));
}

TEST(WakeSignal, ASleepingConsumerIsWoken) {
  WakeSignal w;
  std::atomic<bool> woken{false};
  std::atomic<bool> timed_out{false};
  std::thread consumer([&] {
    const std::uint32_t token = w.prepareWait();
    const auto start = Clock::now();
    while (w.events() == token && !ranIntoTimeout(start)) w.wait(token, kLongTimeoutNs);  // spurious returns loop
    timed_out = ranIntoTimeout(start);
    woken = true;
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // most likely asleep by now; either way must work
  w.notify();
  consumer.join();
  EXPECT_TRUE(woken);
  EXPECT_FALSE(timed_out);
}

// The publisher's pattern (service.cpp) under stress: every item pushed is
// consumed, and no wait ever needs its timeout to see an item.
TEST(WakeSignal, ProducerConsumerNeverLosesAWakeUp) {
  constexpr int kItems = 20'000;
  SpscQueue<int> queue(64);
  WakeSignal w;
  std::atomic<int> timeouts{0};
  long long sum = 0;
  std::thread consumer([&] {
    int received = 0, value = 0;
    while (received < kItems) {
      if (queue.tryPop(value)) {
        sum += value;
        ++received;
        continue;
      }
      const std::uint32_t token = w.prepareWait();
      if (queue.tryPop(value)) {
        w.cancelWait();
        sum += value;
        ++received;
        continue;
      }
      const auto start = Clock::now();
      w.wait(token, kLongTimeoutNs);
      if (ranIntoTimeout(start)) ++timeouts;
    }
  });
  for (int i = 1; i <= kItems; ++i) {
    while (!queue.tryPush(i)) std::this_thread::yield();
    w.notify();
    if (i % 64 == 0) std::this_thread::yield();  // let the consumer fall asleep now and then
  }
  consumer.join();
  EXPECT_EQ(sum, static_cast<long long>(kItems) * (kItems + 1) / 2);
  EXPECT_EQ(timeouts.load(), 0);
}

}  // namespace
}  // namespace rilo
