#pragma once
// Runs the real rilod binary (built beside the test binary) as a child
// process on a private loopback DDS domain and collects what it publishes, the
// way any ROS 2 node would see it. Shared by the end-to-end tests.
#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "dds/participant.h"
#include "dds/subscriber.h"
#include "service_test_support.h"
#include "support/child_process.h"

namespace rilo::testing {

/// Factor on the tests' wall-clock limits: RILO_TEST_TIME_SCALE (default 1),
/// e.g. 10 under ThreadSanitizer (scripts/tsan-service.sh). Never shortens them.
inline double timeScale() {
  const char* env = std::getenv("RILO_TEST_TIME_SCALE");
  const double scale = env != nullptr ? std::atof(env) : 1.0;
  return scale > 1.0 ? scale : 1.0;
}

/// A domain of its own per test process (tests run in parallel under ctest -j).
inline std::uint32_t testDomain() { return 100 + static_cast<std::uint32_t>(::getpid() % 130); }

/// Starts rilod with `config`; its stdout and stderr go to `log` when given.
inline pid_t startRilod(const std::filesystem::path& config, double duration_s, const std::filesystem::path& log = {}) {
  const std::string exe = (binaryDir() / "rilod").string();
  const std::string cfg = config.string();
  const std::string dur = std::to_string(duration_s);
  const std::string log_path = log.string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (!log_path.empty()) {
      const int fd = ::open(log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd >= 0) {
        ::dup2(fd, STDOUT_FILENO);
        ::dup2(fd, STDERR_FILENO);
        ::close(fd);
      }
    }
    ::execl(exe.c_str(), exe.c_str(), "--config", cfg.c_str(), "--seconds", dur.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  return pid;
}

/// Everything one rilod run published, as received.
struct RilodOutput {
  int exit_code = -2;
  double wall_s = 0.0;
  std::vector<dds::OdometryMessage> odometry;
  std::vector<dds::PoseMessage> poses;
  std::vector<dds::StatusMessage> status;
  std::string log;  ///< rilod's stdout + stderr
};

/// Writes `config_text` into `dir`, runs rilod on it (stopped by --seconds
/// after `duration_s`) while subscribing on testDomain(), and returns what
/// arrived once rilod exited (killed after `timeout` x timeScale()).
inline RilodOutput runRilod(const TempDir& dir, const std::string& config_text, double duration_s,
                            std::chrono::seconds timeout) {
  writeFile(dir / "rilod.yaml", config_text);
  dds::ParticipantOptions po;
  po.domain_id = testDomain();
  po.config_xml = dds::loopbackConfigXml();
  dds::Participant participant(po);
  dds::Subscriber subscriber(participant);

  RilodOutput out;
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = startRilod(dir / "rilod.yaml", duration_s, dir / "rilod.log");
  if (pid <= 0) return out;
  const auto end = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(timeout * timeScale());
  while (std::chrono::steady_clock::now() < end) {
    subscriber.waitForData(std::chrono::milliseconds(20));
    subscriber.takeOdometry(out.odometry);
    subscriber.takePose(out.poses);
    subscriber.takeStatus(out.status);
    if (const auto exited = exitedCode(pid)) {
      out.exit_code = *exited;
      break;
    }
  }
  if (out.exit_code == -2) out.exit_code = waitExit(pid, std::chrono::milliseconds(1000));
  // The last reliable samples may still be in flight.
  subscriber.waitForData(std::chrono::milliseconds(50));
  subscriber.takePose(out.poses);
  subscriber.takeStatus(out.status);
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.log = readFile(dir / "rilod.log");
  return out;
}

}  // namespace rilo::testing
