#pragma once
// `rilo listen`: subscribe to rilod's DDS topics (odometry, pose, status, or
// TF) and print what arrives: poses, per-topic rate and latency, one line per
// sample (or one JSON object per line with --json).
#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct ListenOptions {
  std::string topic = "all";  ///< odometry | pose | status | tf | all (odometry, pose and status)
  std::uint64_t count = 0;    ///< stop after this many samples (0 = until interrupted)
  bool json = false;          ///< one JSON object per line
  std::uint32_t domain = 0;   ///< DDS domain id
  double timeout_s = 0.0;     ///< fail when nothing arrives for this long (0 = wait forever)
  bool loopback = false;      ///< Cyclone config limited to the loopback interface
  std::string odometry_topic = "rt/rilo/odometry";
  std::string pose_topic = "rt/rilo/pose";
  std::string status_topic = "rt/rilo/status";
  std::string tf_topic = "rt/tf";
};

/// Runs the listener; returns the process exit code (0 done or interrupted,
/// 1 set-up error, 2 timeout). Throws only what CLI11 should report.
int runListen(const ListenOptions& options);

/// Registers the `listen` subcommand; it exits through CLI::RuntimeError(code)
/// when the code is not 0. Link: rilo_dds, CLI11::CLI11.
void addListenCommand(CLI::App& app);

}  // namespace rilo::tool
