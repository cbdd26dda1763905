#pragma once
// `rilo sim OUT`: simulate a person walking through an office with a UWB tag
// and an IMU (hal/sim/office_scenario.h) and write the session as a recording
// folder (docs/recording-format.md), then print a short summary.
#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct SimOptions {
  std::string out;               ///< recording folder to create
  std::uint64_t seed = 1;
  double minutes = 2.0;
  double range_hz = 40.0;        ///< total ranging rate (all anchors)
  int anchors = 8;
  double nlos_severity = 1.0;
  double imu_hz = 800.0;
  int ranges_per_cycle = 4;
  double packet_loss = 0.05;
  std::string plan = "default";  ///< default | random
  double truth_hz = 200.0;
  bool start_moving = false;
  bool force = false;            ///< replace a recording already in `out`
};

/// Simulates and writes the recording; returns the process exit code (0 ok,
/// 1 failure, the message already printed on stderr).
int runSim(const SimOptions& options);

/// Registers the `sim` subcommand; it exits through CLI::RuntimeError(code)
/// when the code is not 0. Link: rilo_sim, rilo_recording, CLI11::CLI11.
void addSimCommand(CLI::App& app);

}  // namespace rilo::tool
