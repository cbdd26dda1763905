// sd_notify wrapper and watchdog pinger against a real AF_UNIX datagram socket
// bound by the test, NOTIFY_SOCKET pointing at it (what systemd does).
// The pinger runs on a fake heartbeat clock, and the assertions wait on its
// check counter, not on wall-clock time.
#include "rilod/notify.h"

#include <gtest/gtest.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "service/service_test_support.h"

namespace rilo {
namespace {

/// Sets (or unsets, with nullopt) an environment variable for the scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, std::optional<std::string> value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    if (value) {
      ::setenv(name, value->c_str(), 1);
    } else {
      ::unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (old_) {
      ::setenv(name_, old_->c_str(), 1);
    } else {
      ::unsetenv(name_);
    }
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;

 private:
  const char* name_;
  std::optional<std::string> old_;
};

/// A bound AF_UNIX datagram socket: the test's stand-in for systemd.
class NotifySocket {
 public:
  explicit NotifySocket(const std::filesystem::path& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string p = path.string();
    if (p.size() >= sizeof(addr.sun_path)) throw std::runtime_error("socket path too long: " + p);
    std::memcpy(addr.sun_path, p.c_str(), p.size() + 1);
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
      throw std::runtime_error("bind " + p + ": " + std::strerror(errno));
    }
  }
  ~NotifySocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  /// The next datagram, or nullopt if none arrives within `timeout`.
  std::optional<std::string> receive(std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) {
    pollfd pfd{fd_, POLLIN, 0};
    const int ready = ::poll(&pfd, 1, static_cast<int>(timeout.count()));
    if (ready <= 0) return std::nullopt;
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof(buf), 0);
    if (n < 0) return std::nullopt;
    return std::string(buf, static_cast<std::size_t>(n));
  }
  /// Every datagram already queued.
  std::vector<std::string> drain() {
    std::vector<std::string> out;
    while (auto m = receive(std::chrono::milliseconds(0))) out.push_back(*m);
    return out;
  }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
  int fd_ = -1;
};

/// Waits (yielding) until `done()` or a generous deadline; returns done().
template <typename Done>
bool waitFor(Done done, std::chrono::seconds deadline = std::chrono::seconds(20)) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (!done() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return done();
}

class NotifyTest : public ::testing::Test {
 protected:
  testing::TempDir dir_{"rilo-notify"};
  NotifySocket socket_{dir_ / "notify.sock"};
  ScopedEnv notify_socket_{"NOTIFY_SOCKET", socket_.path().string()};
};

TEST_F(NotifyTest, MessagesArriveOnTheSocket) {
  EXPECT_TRUE(notify::enabled());
  EXPECT_GT(notify::ready(), 0);
  EXPECT_EQ(socket_.receive(), "READY=1");
  EXPECT_GT(notify::status("tracking, 4 anchors"), 0);
  EXPECT_EQ(socket_.receive(), "STATUS=tracking, 4 anchors");
  EXPECT_GT(notify::watchdog(), 0);
  EXPECT_EQ(socket_.receive(), "WATCHDOG=1");
  EXPECT_GT(notify::stopping(), 0);
  EXPECT_EQ(socket_.receive(), "STOPPING=1");
  EXPECT_GT(notify::readyWithStatus("up"), 0);
  EXPECT_EQ(socket_.receive(), "READY=1\nSTATUS=up");
  EXPECT_GT(notify::send("RELOADING=1"), 0);
  EXPECT_EQ(socket_.receive(), "RELOADING=1");
}

TEST_F(NotifyTest, StatusCannotInjectAssignments) {
  EXPECT_GT(notify::status("degraded\nREADY=1\r\nx"), 0);
  EXPECT_EQ(socket_.receive(), "STATUS=degraded READY=1  x");
  EXPECT_GT(notify::status(std::string(5000, 'a')), 0);
  const auto long_status = socket_.receive();
  ASSERT_TRUE(long_status.has_value());
  EXPECT_EQ(long_status->size(), std::string("STATUS=").size() + 1000);
}

TEST_F(NotifyTest, NoOpWithoutNotifySocket) {
  ScopedEnv unset("NOTIFY_SOCKET", std::nullopt);
  EXPECT_FALSE(notify::enabled());
  EXPECT_EQ(notify::ready(), 0);
  EXPECT_EQ(notify::status("x"), 0);
  EXPECT_EQ(notify::watchdog(), 0);
  EXPECT_EQ(notify::stopping(), 0);
  EXPECT_TRUE(socket_.drain().empty());
}

TEST_F(NotifyTest, SendFailureIsReturnedNotThrown) {
  ScopedEnv missing("NOTIFY_SOCKET", (dir_ / "nobody-listens.sock").string());
  EXPECT_LT(notify::ready(), 0);
}

TEST(WatchdogIntervalTest, ReadsWatchdogUsecForThisProcess) {
  {
    ScopedEnv usec("WATCHDOG_USEC", std::nullopt);
    EXPECT_FALSE(notify::watchdogInterval().has_value());
  }
  {
    ScopedEnv usec("WATCHDOG_USEC", "250000");
    ScopedEnv pid("WATCHDOG_PID", std::nullopt);
    ASSERT_TRUE(notify::watchdogInterval().has_value());
    EXPECT_EQ(notify::watchdogInterval()->count(), 250000);
  }
  {
    ScopedEnv usec("WATCHDOG_USEC", "250000");
    ScopedEnv pid("WATCHDOG_PID", std::to_string(::getpid()));
    EXPECT_TRUE(notify::watchdogInterval().has_value());
  }
  {
    // Meant for another process (e.g. the parent that forked us).
    ScopedEnv usec("WATCHDOG_USEC", "250000");
    ScopedEnv pid("WATCHDOG_PID", std::to_string(::getpid() + 1));
    EXPECT_FALSE(notify::watchdogInterval().has_value());
  }
  {
    ScopedEnv usec("WATCHDOG_USEC", "garbage");
    EXPECT_FALSE(notify::watchdogInterval().has_value());
  }
}

/// Fake clock for the heartbeat and the pinger.
struct FakeClock {
  std::atomic<std::int64_t> now_ns{1'000'000'000};
  std::function<std::int64_t()> fn() {
    return [this] { return now_ns.load(); };
  }
};

notify::WatchdogPingerOptions fastOptions(FakeClock& clock) {
  notify::WatchdogPingerOptions o;
  o.interval = std::chrono::milliseconds(20);  // a check every 10 ms of real time
  o.heartbeat_max_age_ns = 500'000'000;        // on the fake clock
  o.now_ns = clock.fn();
  return o;
}

std::size_t countWatchdogMessages(const std::vector<std::string>& messages) {
  std::size_t n = 0;
  for (const auto& m : messages) n += m == "WATCHDOG=1" ? 1 : 0;
  return n;
}

TEST_F(NotifyTest, WatchdogPingsOnlyWhileTheHeartbeatIsAlive) {
  FakeClock clock;
  Heartbeat heartbeat;
  heartbeat.beat(clock.now_ns.load());
  notify::WatchdogPinger pinger(heartbeat, fastOptions(clock));
  EXPECT_EQ(pinger.period(), std::chrono::milliseconds(10));

  // Alive: pings arrive as WATCHDOG=1 datagrams.
  ASSERT_TRUE(waitFor([&] { return pinger.pings() >= 3; }));
  for (int i = 0; i < 3; ++i) EXPECT_EQ(socket_.receive(), "WATCHDOG=1");
  EXPECT_FALSE(pinger.stalled());

  // The loop stops beating: its last beat ages past the limit.
  clock.now_ns += 2'000'000'000;
  const std::uint64_t c0 = pinger.checks();
  // The check in flight when the clock moved may still have pinged; the
  // second one after it has certainly seen the stale heartbeat.
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 2; }));
  const std::uint64_t pings_at_stall = pinger.pings();
  socket_.drain();
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 8; }));
  EXPECT_EQ(pinger.pings(), pings_at_stall) << "pinged with a stale heartbeat";
  EXPECT_TRUE(socket_.drain().empty()) << "WATCHDOG=1 sent with a stale heartbeat";
  EXPECT_TRUE(pinger.stalled());
  EXPECT_GE(pinger.skipped(), 6u);

  // The loop resumes: pings resume.
  heartbeat.beat(clock.now_ns.load());
  ASSERT_TRUE(waitFor([&] { return pinger.pings() > pings_at_stall; }));
  EXPECT_EQ(socket_.receive(), "WATCHDOG=1");
  pinger.stop();
  EXPECT_FALSE(pinger.thread().joinable());
}

TEST_F(NotifyTest, NoPingBeforeTheFirstBeatWithoutGrace) {
  FakeClock clock;
  Heartbeat heartbeat;
  notify::WatchdogPinger pinger(heartbeat, fastOptions(clock));
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= 4; }));
  pinger.stop();
  EXPECT_EQ(pinger.pings(), 0u);
  EXPECT_EQ(countWatchdogMessages(socket_.drain()), 0u);
}

TEST_F(NotifyTest, StartupGraceCoversTheTimeBeforeTheFirstBeat) {
  FakeClock clock;
  Heartbeat heartbeat;
  auto options = fastOptions(clock);
  options.startup_grace_ns = 10'000'000'000;
  notify::WatchdogPinger pinger(heartbeat, options);
  ASSERT_TRUE(waitFor([&] { return pinger.pings() >= 2; }));
  EXPECT_GE(countWatchdogMessages(socket_.drain()), 1u);

  // Grace over and still no beat: silence.
  clock.now_ns += 20'000'000'000;
  const std::uint64_t c0 = pinger.checks();
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 2; }));
  const std::uint64_t pings = pinger.pings();
  socket_.drain();
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 6; }));
  EXPECT_EQ(pinger.pings(), pings);
  EXPECT_EQ(countWatchdogMessages(socket_.drain()), 0u);
}

TEST_F(NotifyTest, EveryWatchedThreadMustBeat) {
  // Issue 37: with the estimator's heartbeat alone, a hung publisher kept
  // the pings going.
  FakeClock clock;
  Heartbeat estimator, publisher, source;
  const std::int64_t t0 = clock.now_ns.load();
  estimator.beat(t0);
  publisher.beat(t0);
  source.beat(t0);
  std::atomic<bool> source_ended{false};
  notify::WatchdogPinger pinger({{"estimator", &estimator, {}},
                                 {"publisher", &publisher, {}},
                                 {"source 0 (replay)", &source, [&] { return source_ended.load(); }}},
                                fastOptions(clock));
  ASSERT_TRUE(waitFor([&] { return pinger.pings() >= 2; }));
  EXPECT_EQ(pinger.stalledThread(), "");

  // The publisher hangs while the estimator and the source go on.
  clock.now_ns += 2'000'000'000;
  estimator.beat(clock.now_ns.load());
  source.beat(clock.now_ns.load());
  const std::uint64_t c0 = pinger.checks();
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 2; }));
  const std::uint64_t pings = pinger.pings();
  socket_.drain();
  ASSERT_TRUE(waitFor([&] { return pinger.checks() >= c0 + 6; }));
  EXPECT_EQ(pinger.pings(), pings) << "pinged with the publisher stuck";
  EXPECT_EQ(countWatchdogMessages(socket_.drain()), 0u);
  EXPECT_TRUE(pinger.stalled());
  EXPECT_EQ(pinger.stalledThread(), "publisher");

  // It resumes; then the replay source ends its data and stops beating on purpose.
  publisher.beat(clock.now_ns.load());
  ASSERT_TRUE(waitFor([&] { return pinger.pings() > pings; }));
  source_ended.store(true);
  clock.now_ns += 2'000'000'000;
  estimator.beat(clock.now_ns.load());
  publisher.beat(clock.now_ns.load());
  const std::uint64_t p1 = pinger.pings();
  ASSERT_TRUE(waitFor([&] { return pinger.pings() >= p1 + 3; })) << "an ended source must not stop the pings";
  EXPECT_EQ(pinger.stalledThread(), "");
}

TEST(WatchdogPingerTest, RefusesAnEmptyListOrAMissingHeartbeat) {
  notify::WatchdogPingerOptions o;
  o.interval = std::chrono::milliseconds(100);
  EXPECT_THROW(notify::WatchdogPinger(std::vector<notify::WatchedThread>{}, o), std::invalid_argument);
  EXPECT_THROW(notify::WatchdogPinger(std::vector<notify::WatchedThread>{{"status", nullptr, {}}}, o),
               std::invalid_argument);
}

TEST(WatchdogPingerTest, AHeartbeatTimeoutMustFitTheUnitsWatchdogPeriod) {
  using std::chrono::seconds;
  EXPECT_EQ(notify::heartbeatTimeoutProblem(1'000'000'000, seconds(5)), "");
  const std::string problem = notify::heartbeatTimeoutProblem(100'000'000'000, seconds(5));
  EXPECT_NE(problem.find("watchdog.heartbeat_timeout_s (100 s)"), std::string::npos) << problem;
  EXPECT_NE(problem.find("WatchdogSec=5 s"), std::string::npos) << problem;
  EXPECT_NE(notify::heartbeatTimeoutProblem(5'000'000'000, seconds(5)), "");  // equal does not fit either
}

TEST(WatchdogPingerTest, RejectsBadOptions) {
  Heartbeat heartbeat;
  notify::WatchdogPingerOptions o;
  o.interval = std::chrono::microseconds(0);
  EXPECT_THROW(notify::WatchdogPinger(heartbeat, o), std::invalid_argument);
  o.interval = std::chrono::milliseconds(100);
  o.heartbeat_max_age_ns = 0;
  EXPECT_THROW(notify::WatchdogPinger(heartbeat, o), std::invalid_argument);
  o.heartbeat_max_age_ns = 1;
  o.startup_grace_ns = -1;
  EXPECT_THROW(notify::WatchdogPinger(heartbeat, o), std::invalid_argument);
}

TEST(WatchdogPingerTest, StopsPromptlyWithALongInterval) {
  Heartbeat heartbeat;
  notify::WatchdogPingerOptions o;
  o.interval = std::chrono::hours(1);
  int pings = 0;
  o.ping = [&] { return ++pings; };
  auto pinger = std::make_unique<notify::WatchdogPinger>(heartbeat, o);
  ASSERT_TRUE(waitFor([&] { return pinger->checks() >= 1; }));
  pinger.reset();  // must not wait for the half-hour period
  EXPECT_EQ(pings, 0);
}

TEST(WatchdogPingerTest, StartsOnlyWhenSystemdAsks) {
  Heartbeat heartbeat;
  {
    ScopedEnv usec("WATCHDOG_USEC", std::nullopt);
    EXPECT_EQ(notify::startWatchdogIfRequested(heartbeat, 1'000'000'000), nullptr);
  }
  {
    ScopedEnv usec("WATCHDOG_USEC", "4000000");
    ScopedEnv pid("WATCHDOG_PID", std::nullopt);
    ScopedEnv socket("NOTIFY_SOCKET", std::nullopt);  // pings go nowhere
    auto pinger = notify::startWatchdogIfRequested(heartbeat, 1'000'000'000);
    ASSERT_NE(pinger, nullptr);
    EXPECT_EQ(pinger->period(), std::chrono::seconds(2));
  }
}

}  // namespace
}  // namespace rilo
