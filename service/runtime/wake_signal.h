#pragma once
// Wakes one sleeping consumer thread when a producer has published work
// (pushed into a lock-free queue), without a lock and without the consumer
// polling: the publisher thread sleeps until the next IMU sample instead of
// waking every 200 us to look (measured: 6-8 % of a core at 800 Hz on the
// development machine, and up to 200 us of added latency).
//
// Producer, after publishing:      notify();
// Consumer, when it found no work:
//     const auto token = prepareWait();
//     if (<work available now>) { cancelWait(); ... } else wait(token, timeout_ns);
// The consumer must look for work again between prepareWait() and wait():
// a notify() that came before prepareWait() is only seen that way.
//
// Why no wake-up is lost: notify() increments `events_` and then reads
// `waiting_`; prepareWait() sets `waiting_` and then reads `events_`; all four
// are sequentially consistent, so either notify() sees the consumer waiting
// (and wakes it) or prepareWait() reads the incremented count, and the futex
// wait on the old count returns at once (the kernel compares the word
// atomically). The data itself is ordered by its own queue (release/acquire).
//
// Cost: notify() is one atomic increment and one load, plus a FUTEX_WAKE
// system call (about a microsecond) only while the consumer sleeps. No
// allocation, no lock. Linux only (futex). One consumer; any number of producers.
#include <linux/futex.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <cstdint>

#include "runtime/cpu_hints.h"

namespace rilo {

class WakeSignal {
 public:
  /// Producer side: wakes the consumer if it sleeps in wait().
  void notify() noexcept {
    events_.fetch_add(1, std::memory_order_seq_cst);
    if (waiting_.load(std::memory_order_seq_cst) != 0) {
      syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&events_), FUTEX_WAKE_PRIVATE, 1, nullptr, nullptr, 0);
    }
  }

  /// Consumer side: announces a wait; returns the token for wait().
  std::uint32_t prepareWait() noexcept {
    waiting_.store(1, std::memory_order_seq_cst);
    return events_.load(std::memory_order_seq_cst);
  }
  /// Consumer side: work turned up after prepareWait(); no wait.
  void cancelWait() noexcept { waiting_.store(0, std::memory_order_relaxed); }
  /// Consumer side: sleeps until a notify() after prepareWait(), the
  /// timeout, or a signal (spurious returns are fine: the caller loops).
  void wait(std::uint32_t token, std::int64_t timeout_ns) noexcept {
    timespec timeout{};
    timeout.tv_sec = static_cast<time_t>(timeout_ns / 1'000'000'000);
    timeout.tv_nsec = static_cast<long>(timeout_ns % 1'000'000'000);
    syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(&events_), FUTEX_WAIT_PRIVATE, token, &timeout, nullptr, 0);
    waiting_.store(0, std::memory_order_relaxed);
  }

  /// notify() calls so far (wraps; for tests).
  std::uint32_t events() const noexcept { return events_.load(std::memory_order_relaxed); }

 private:
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t) &&
                    std::atomic<std::uint32_t>::is_always_lock_free,
                "the futex word is the atomic's storage");
  // Own lines: the producer writes events_ per sample, the consumer waiting_.
  alignas(kCacheLineBytes) std::atomic<std::uint32_t> events_{0};
  alignas(kCacheLineBytes) std::atomic<std::uint32_t> waiting_{0};
};

}  // namespace rilo
