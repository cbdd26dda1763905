#pragma once
// rilod's init runner (estimation/tracking/init_attempt_runner.h): one
// worker thread that runs the Localizer's initialization attempts, so the
// estimator thread keeps draining the sensor queues while an attempt solves
// its window (issue 37: 331 ms for a 45 s window here, on the estimator
// thread, and an 8x replay overflowed the queues).
// The thread is started by the constructor and takes the scheduling of the
// thread that constructs it: construct it from a normal thread (rilod: the
// main thread, before the real-time threads start), so that attempts run
// under normal scheduling and yield to the real-time threads.
// Hand-off through one atomic word (wait/notify): the estimator thread never
// takes a lock or blocks in start() and idle().
#include <atomic>
#include <functional>
#include <string>
#include <thread>

#include "estimation/tracking/init_attempt_runner.h"

namespace rilo {

class InitWorker final : public InitAttemptRunner {
 public:
  /// `thread_name`: shown by ps and top (15 characters kept).
  explicit InitWorker(const std::string& thread_name = "rilo-init");
  /// Waits for a running attempt, then ends the thread.
  ~InitWorker() override;
  InitWorker(const InitWorker&) = delete;
  InitWorker& operator=(const InitWorker&) = delete;

  void start(std::function<void()> attempt) override;
  bool idle() const override { return state_.load(std::memory_order_acquire) == kIdle; }
  void wait() override;
  /// Polls every millisecond (an atomic wait has no timeout).
  bool waitFor(double seconds) override;
  /// Attempts run so far.
  unsigned long attemptsRun() const { return runs_.load(std::memory_order_relaxed); }

 private:
  enum : int { kIdle, kBusy, kStop };
  void run();

  std::atomic<int> state_{kIdle};
  std::atomic<unsigned long> runs_{0};
  std::function<void()> attempt_;  ///< written by start() while idle, read by the worker while busy
  std::thread thread_;
};

}  // namespace rilo
