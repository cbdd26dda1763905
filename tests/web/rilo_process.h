#pragma once
// The rilo tool as a child process for the web tests: start it, read the URL
// it prints, stop it.
#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "service/rilod_runner.h"

namespace rilo::testing {

/// Starts build/bin/rilo with `args`, its stdout into `out`.
inline pid_t startRilo(const std::vector<std::string>& args, const std::filesystem::path& out) {
  const std::string exe = (testing::binaryDir() / "rilo").string();
  std::vector<char*> argv{const_cast<char*>(exe.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int fd = ::open(out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, STDOUT_FILENO);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  return pid;
}

/// The URL `rilo view` (or `rilo replay --view`) printed on its first line, or "" after `timeout`.
inline std::string waitForUrl(const std::filesystem::path& out, std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    std::ifstream in(out);
    std::string line;
    if (std::getline(in, line) && line.rfind("http://", 0) == 0) return line;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return {};
}

/// SIGTERM, then the exit code (waitExit: -1 after killing it at 5 s).
inline int stopProcess(pid_t pid) {
  if (pid <= 0) return -1;
  ::kill(pid, SIGTERM);
  return waitExit(pid, std::chrono::milliseconds(5000));
}

/// A child process stopped when the test leaves its scope, a failed
/// assertion included (a leftover rilod or rilo would go on publishing on the
/// test's domain and hold ctest's output pipe open).
class ChildProcess {
 public:
  explicit ChildProcess(pid_t pid) : pid_(pid) {}
  ~ChildProcess() { stop(); }
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  pid_t pid() const { return pid_; }
  /// Stops it now; returns its exit code (stopProcess), -1 if already stopped.
  int stop() {
    const int code = stopProcess(pid_);
    pid_ = -1;
    return code;
  }

 private:
  pid_t pid_;
};

}  // namespace rilo::testing
