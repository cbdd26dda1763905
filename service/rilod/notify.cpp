#include "rilod/notify.h"

#include <systemd/sd-daemon.h>
#include <time.h>

#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>

#include "hal/bus/clock.h"

namespace rilo::notify {

namespace {

constexpr std::size_t kMaxStatusBytes = 1000;

std::string statusLine(std::string_view text) {
  std::string line = "STATUS=";
  const std::size_t n = text.size() < kMaxStatusBytes ? text.size() : kMaxStatusBytes;
  for (std::size_t i = 0; i < n; ++i) {
    const char c = text[i];
    line += (c == '\n' || c == '\r' || c == '\0') ? ' ' : c;
  }
  return line;
}

}  // namespace

bool enabled() noexcept {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  return socket != nullptr && socket[0] != '\0';
}

int send(std::string_view state) noexcept {
  if (!enabled()) return 0;
  try {
    return sd_notify(0, std::string(state).c_str());
  } catch (...) {  // std::bad_alloc: nothing sent
    return -12;    // -ENOMEM
  }
}

int ready() noexcept { return send("READY=1"); }
int stopping() noexcept { return send("STOPPING=1"); }
int watchdog() noexcept { return send("WATCHDOG=1"); }

int status(std::string_view text) noexcept {
  if (!enabled()) return 0;
  try {
    return send(statusLine(text));
  } catch (...) {
    return -12;
  }
}

int readyWithStatus(std::string_view text) noexcept {
  if (!enabled()) return 0;
  try {
    return send("READY=1\n" + statusLine(text));
  } catch (...) {
    return -12;
  }
}

std::optional<std::chrono::microseconds> watchdogInterval() noexcept {
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) <= 0 || usec == 0) return std::nullopt;
  return std::chrono::microseconds(static_cast<std::int64_t>(usec));
}

// --- WatchdogPinger -------------------------------------------------------------

WatchdogPinger::WatchdogPinger(const Heartbeat& heartbeat, WatchdogPingerOptions options)
    : WatchdogPinger(std::vector<WatchedThread>{WatchedThread{"real-time loop", &heartbeat, {}}}, std::move(options)) {}

WatchdogPinger::WatchdogPinger(std::vector<WatchedThread> threads, WatchdogPingerOptions options)
    : threads_(std::move(threads)), options_(std::move(options)), period_(options_.interval / 2) {
  if (threads_.empty()) throw std::invalid_argument("WatchdogPinger: no thread to watch");
  for (const WatchedThread& t : threads_) {
    if (t.heartbeat == nullptr) throw std::invalid_argument("WatchdogPinger: thread '" + t.name + "' has no heartbeat");
  }
  if (options_.interval.count() <= 1) {
    throw std::invalid_argument("WatchdogPinger: interval must be > 1 us, got " +
                                std::to_string(options_.interval.count()) + " us");
  }
  if (options_.heartbeat_max_age_ns <= 0) {
    throw std::invalid_argument("WatchdogPinger: heartbeat_max_age_ns must be > 0");
  }
  if (options_.startup_grace_ns < 0) throw std::invalid_argument("WatchdogPinger: startup_grace_ns must be >= 0");
  if (!options_.now_ns) options_.now_ns = hal::monotonicNowNs;
  if (!options_.ping) options_.ping = [] { return watchdog(); };
  thread_ = std::thread([this] { run(); });
}

const std::string& WatchdogPinger::stalledThread() const noexcept {
  static const std::string none;
  const int i = stalled_index_.load(std::memory_order_acquire);
  return i >= 0 ? threads_[static_cast<std::size_t>(i)].name : none;
}

WatchdogPinger::~WatchdogPinger() { stop(); }

void WatchdogPinger::stop() noexcept {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_requested_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable() && thread_.get_id() != std::this_thread::get_id()) thread_.join();
}

void WatchdogPinger::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  const std::int64_t start_ns = options_.now_ns();
  while (!stop_requested_) {
    // Read the clock before the heartbeats: a beat stamped later counts as fresh.
    const std::int64_t now = options_.now_ns();
    int stale = -1;
    for (std::size_t i = 0; i < threads_.size() && stale < 0; ++i) {
      const WatchedThread& t = threads_[i];
      if (t.finished && t.finished()) continue;
      const bool in_grace = t.heartbeat->count() == 0 && now - start_ns < options_.startup_grace_ns;
      if (!in_grace && !t.heartbeat->isAlive(now, options_.heartbeat_max_age_ns)) stale = static_cast<int>(i);
    }
    const bool alive = stale < 0;
    if (alive) {
      options_.ping();
      pings_.fetch_add(1, std::memory_order_release);
    } else {
      skipped_.fetch_add(1, std::memory_order_release);
    }
    stalled_index_.store(stale, std::memory_order_release);
    stalled_.store(!alive, std::memory_order_release);
    checks_.fetch_add(1, std::memory_order_release);
    wake_.wait_for(lock, period_, [this] { return stop_requested_; });
  }
}

std::unique_ptr<WatchdogPinger> startWatchdogIfRequested(const Heartbeat& heartbeat,
                                                         std::int64_t heartbeat_max_age_ns,
                                                         std::int64_t startup_grace_ns) {
  return startWatchdogIfRequested(std::vector<WatchedThread>{WatchedThread{"real-time loop", &heartbeat, {}}},
                                  heartbeat_max_age_ns, startup_grace_ns);
}

std::unique_ptr<WatchdogPinger> startWatchdogIfRequested(std::vector<WatchedThread> threads,
                                                         std::int64_t heartbeat_max_age_ns,
                                                         std::int64_t startup_grace_ns) {
  const auto interval = watchdogInterval();
  if (!interval) return nullptr;
  WatchdogPingerOptions options;
  options.interval = *interval;
  options.heartbeat_max_age_ns = heartbeat_max_age_ns;
  options.startup_grace_ns = startup_grace_ns;
  return std::make_unique<WatchdogPinger>(std::move(threads), std::move(options));
}

std::string heartbeatTimeoutProblem(std::int64_t heartbeat_max_age_ns, std::chrono::microseconds interval) {
  const std::int64_t interval_ns = interval.count() * 1000;
  if (heartbeat_max_age_ns < interval_ns) return "";
  char text[256];
  std::snprintf(text, sizeof text,
                "watchdog.heartbeat_timeout_s (%.3g s) must be below the unit's watchdog period (WatchdogSec=%.3g s, "
                "WATCHDOG_USEC): a stuck thread would keep the pings going for up to the timeout, longer than the unit allows",
                static_cast<double>(heartbeat_max_age_ns) * 1e-9, static_cast<double>(interval_ns) * 1e-9);
  return text;
}

}  // namespace rilo::notify
