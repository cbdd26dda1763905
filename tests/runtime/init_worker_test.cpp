// InitWorker (rilod's init runner): attempts run on its own thread, one at a
// time; idle() says when one has returned and its writes are visible; wait()
// and the destructor wait for it; a throwing attempt does not end the thread.
// No check asks how fast anything was.
#include "runtime/init_worker.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <thread>

namespace rilo {
namespace {

TEST(InitWorker, RunsTheAttemptOnItsOwnThread) {
  InitWorker worker;
  EXPECT_TRUE(worker.idle());
  std::thread::id ran_on;
  worker.start([&] { ran_on = std::this_thread::get_id(); });
  worker.wait();
  EXPECT_TRUE(worker.idle());
  EXPECT_NE(ran_on, std::thread::id());
  EXPECT_NE(ran_on, std::this_thread::get_id());
  EXPECT_EQ(worker.attemptsRun(), 1u);
}

TEST(InitWorker, IsBusyUntilTheAttemptReturnsAndRefusesASecondOne) {
  InitWorker worker;
  std::atomic<bool> release{false}, entered{false};
  int written = 0;  // plain: idle() must publish it (acquire / release)
  worker.start([&] {
    entered.store(true);
    while (!release.load()) std::this_thread::yield();
    written = 42;
  });
  while (!entered.load()) std::this_thread::yield();
  EXPECT_FALSE(worker.idle());
  EXPECT_THROW(worker.start([] {}), std::logic_error);
  release.store(true);
  while (!worker.idle()) std::this_thread::yield();
  EXPECT_EQ(written, 42);
}

TEST(InitWorker, WaitForReturnsWhetherTheAttemptEnded) {
  InitWorker worker;
  EXPECT_TRUE(worker.waitFor(0.0)) << "idle";
  std::atomic<bool> release{false};
  worker.start([&] {
    while (!release.load()) std::this_thread::yield();
  });
  EXPECT_FALSE(worker.waitFor(0.01)) << "held until released";
  release.store(true);
  EXPECT_TRUE(worker.waitFor(std::numeric_limits<double>::infinity()));
  EXPECT_TRUE(worker.idle());
}

TEST(InitWorker, ManyAttemptsInARowAreEachRunOnce) {
  InitWorker worker;
  int count = 0;
  for (int i = 0; i < 2000; ++i) {
    worker.start([&] { ++count; });
    worker.wait();
  }
  EXPECT_EQ(count, 2000);
  EXPECT_EQ(worker.attemptsRun(), 2000u);
}

TEST(InitWorker, TheDestructorWaitsForTheRunningAttempt) {
  std::atomic<bool> finished{false}, entered{false};
  {
    InitWorker worker;
    worker.start([&] {
      entered.store(true);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      finished.store(true);
    });
    while (!entered.load()) std::this_thread::yield();
  }
  EXPECT_TRUE(finished.load());
}

TEST(InitWorker, AThrowingAttemptDoesNotEndTheThread) {
  InitWorker worker;
  worker.start([] { throw std::runtime_error("solver failed"); });
  worker.wait();
  bool ran = false;
  worker.start([&] { ran = true; });
  worker.wait();
  EXPECT_TRUE(ran);
  EXPECT_EQ(worker.attemptsRun(), 2u);
}

}  // namespace
}  // namespace rilo
