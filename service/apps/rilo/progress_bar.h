#pragma once
// A progress bar on stderr for the tool's long commands (report, accuracy):
// "rilo <command>: [#####.....] 12/64 runs, 1:05 elapsed, ~2:10 left",
// rewritten in place on a terminal, one log line per tenth otherwise.
#include <chrono>
#include <cstddef>
#include <string>

namespace rilo::tool {

/// "m:ss" or "h:mm:ss".
std::string formatDuration(double s);

class ProgressBar {
 public:
  /// command: the subcommand's name for the terminal line ("report"); what: the counted things ("runs").
  ProgressBar(std::string command, std::string what);
  ~ProgressBar();
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void operator()(std::size_t done, std::size_t total);

 private:
  std::string command_;
  std::string what_;
  bool tty_;
  bool printed_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

}  // namespace rilo::tool
