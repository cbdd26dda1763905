#pragma once
// systemd notification (sd_notify(3)) for a Type=notify service:
//   READY=1     once sources and DDS are up,
//   STATUS=...  one human-readable line shown by `systemctl status`,
//   WATCHDOG=1  from WatchdogPinger only while every watched thread beats
//               (sources, estimator, publisher, status),
//   STOPPING=1  as soon as the stop request (SIGTERM) is seen.
// Every call is a no-op returning 0 when NOTIFY_SOCKET is unset (run from a
// shell, tests, CI), so the service never needs to know how it was started.
// Each call opens, sends and closes a datagram socket (libsystemd): cheap,
// thread-safe, but a system call: never from the IMU-rate path.
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "runtime/heartbeat.h"

namespace rilo::notify {

/// True if NOTIFY_SOCKET is set (the process runs under systemd with
/// Type=notify, or a test pretends so).
bool enabled() noexcept;

/// Sends `state` (newline-separated VAR=value assignments) as is. Returns > 0
/// if sent, 0 if notification is not enabled, -errno on failure (the service
/// keeps running: a failed notification is logged by the caller, never fatal).
int send(std::string_view state) noexcept;

int ready() noexcept;                     ///< READY=1
int stopping() noexcept;                  ///< STOPPING=1
int watchdog() noexcept;                  ///< WATCHDOG=1
/// STATUS=<text>; newlines in `text` become spaces (a newline would start a
/// new assignment), and it is cut at 1000 bytes.
int status(std::string_view text) noexcept;
/// READY=1 and STATUS=<text> in one datagram.
int readyWithStatus(std::string_view text) noexcept;

/// The watchdog interval systemd expects pings within (WatchdogSec=, passed
/// as WATCHDOG_USEC and checked against WATCHDOG_PID by sd_watchdog_enabled),
/// or nullopt when the watchdog is off for this process.
std::optional<std::chrono::microseconds> watchdogInterval() noexcept;

struct WatchdogPingerOptions {
  /// systemd's interval; pings are sent every interval / 2 (sd_watchdog_enabled(3)).
  std::chrono::microseconds interval{0};
  /// The heartbeat must be at most this old (ns) for a ping. A stuck
  /// real-time loop then stops the pings and systemd restarts the service.
  std::int64_t heartbeat_max_age_ns = 1'000'000'000;
  /// Before the first beat, keep pinging for this long (ns) after the pinger
  /// starts: start-up work between READY=1 and the loop's first beat (DDS
  /// discovery, the initialization window) must not trip the watchdog.
  /// 0 = no grace: no ping before the first beat.
  std::int64_t startup_grace_ns = 0;
  /// Clock the heartbeat's beats are stamped with (ns); empty = CLOCK_MONOTONIC.
  std::function<std::int64_t()> now_ns;
  /// Sends one ping; empty = watchdog() (for tests).
  std::function<int()> ping;
};

/// One thread the watchdog watches.
struct WatchedThread {
  std::string name;                ///< for the log: "estimator", "source 0 (dwm3000 /dev/spidev0.0)"
  const Heartbeat* heartbeat = nullptr;  ///< must outlive the pinger
  /// True once the thread ended its work on purpose (a replay at the end of
  /// its data): it no longer beats and is no longer judged. Empty: never.
  std::function<bool()> finished;
};

/// A thread that checks `heartbeat` every interval / 2 and sends WATCHDOG=1
/// only while it is alive (or, before the first beat, within the start-up
/// grace). Once the loop stops beating, pings stop within
/// heartbeat_max_age_ns + interval / 2, and systemd restarts the service one
/// WatchdogSec after the last ping: choose heartbeat_max_age_ns well below
/// WatchdogSec. Started by
/// the constructor, stopped and joined by stop() or the destructor (within
/// one check period at most: the wait is interruptible).
class WatchdogPinger {
 public:
  /// Throws std::invalid_argument if options.interval is not positive or
  /// heartbeat_max_age_ns is not positive. `heartbeat` must outlive the pinger.
  WatchdogPinger(const Heartbeat& heartbeat, WatchdogPingerOptions options);
  /// Pings only while every thread in `threads` beats (or is finished, or,
  /// before its first beat, within the start-up grace): a hung publisher or
  /// source stops the pings as a hung estimator does. Throws
  /// std::invalid_argument for an empty list or a null heartbeat.
  WatchdogPinger(std::vector<WatchedThread> threads, WatchdogPingerOptions options);
  ~WatchdogPinger();
  WatchdogPinger(const WatchdogPinger&) = delete;
  WatchdogPinger& operator=(const WatchdogPinger&) = delete;

  void stop() noexcept;

  std::uint64_t checks() const noexcept { return checks_.load(std::memory_order_acquire); }
  std::uint64_t pings() const noexcept { return pings_.load(std::memory_order_acquire); }
  /// Checks that found the heartbeat stale (no ping sent).
  std::uint64_t skipped() const noexcept { return skipped_.load(std::memory_order_acquire); }
  /// True if the last check found the heartbeat stale.
  bool stalled() const noexcept { return stalled_.load(std::memory_order_acquire); }
  /// The first thread the last check found stale ("" while every one beats).
  const std::string& stalledThread() const noexcept;
  std::chrono::microseconds period() const noexcept { return period_; }
  /// For real-time settings (name, affinity) of the watchdog thread.
  std::thread& thread() noexcept { return thread_; }

 private:
  void run();

  std::vector<WatchedThread> threads_;
  WatchdogPingerOptions options_;
  std::chrono::microseconds period_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stop_requested_ = false;
  std::atomic<std::uint64_t> checks_{0}, pings_{0}, skipped_{0};
  std::atomic<bool> stalled_{false};
  std::atomic<int> stalled_index_{-1};
  std::thread thread_;
};

/// A pinger if systemd asked for a watchdog (watchdogInterval()), else null.
std::unique_ptr<WatchdogPinger> startWatchdogIfRequested(const Heartbeat& heartbeat,
                                                         std::int64_t heartbeat_max_age_ns,
                                                         std::int64_t startup_grace_ns = 0);
std::unique_ptr<WatchdogPinger> startWatchdogIfRequested(std::vector<WatchedThread> threads,
                                                         std::int64_t heartbeat_max_age_ns,
                                                         std::int64_t startup_grace_ns = 0);

/// Why a heartbeat timeout cannot work under the unit's watchdog period
/// (`interval`, WATCHDOG_USEC): pings stop only heartbeat_max_age_ns after
/// the last beat, so a timeout at or past the period lets systemd kill a
/// healthy service or never notice a stuck one. Empty when it fits.
std::string heartbeatTimeoutProblem(std::int64_t heartbeat_max_age_ns, std::chrono::microseconds interval);

}  // namespace rilo::notify
