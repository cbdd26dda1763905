#pragma once
// `rilo sim OUT`: simulate a person walking through an office with a UWB tag
// and an IMU (sim/office_scenario.h) and write the session as a recording
// folder (docs/recording-format.md), then print a short summary. With --tdoa
// the tag listens to UWB TDoA instead of SS-TWR ranging (sim/office_tdoa.h),
// with --ultrasonic ceiling beacons add ultrasonic ranges (office_ultrasonic.h).
// --plan hall simulates an open hall with the anchors around it instead of an
// office floor (sim/office_hall.h).
#include <cstdint>
#include <string>

#include "sim/walk.h"

namespace CLI {
class App;
}

namespace rilo::tool {

struct SimOptions {
  std::string out;               ///< recording folder to create
  std::uint64_t seed = 1;
  double seconds = 120.0;        ///< duration of the session
  double range_hz = 40.0;        ///< total ranging rate (all anchors)
  int anchors = 8;
  double nlos_severity = 1.0;
  double imu_hz = 800.0;
  int ranges_per_cycle = 4;
  double packet_loss = 0.05;
  std::string plan = "default";  ///< default | random | hall
  double hall_length = 16.0;     ///< --plan hall: size along x (m)
  double hall_width = 10.0;      ///< --plan hall: size along y (m)
  double truth_hz = 200.0;
  bool start_moving = false;
  bool first_path = true;        ///< the receiver reports first-path power (false: --no-first-path)
  double body_height_m = sim::WalkParams{}.body_height_m;  ///< IMU height of the standing wearer (m); the tag sits 0.1 m above it
  bool overwrite = false;        ///< replace a recording already in `out`

  // Second system (IMU-Ultrasonic-UWB paper): UWB TDoA and ultrasonic beacons, off by default.
  bool tdoa = false;             ///< TDoA instead of SS-TWR (meta ranging: tdoa)
  double tdoa_hz = 20.0;         ///< TDoA rounds per second, one packet per anchor each (paper: 20 Hz)
  double packet_reception = 0.95;  ///< P(a heard TDoA packet is received) (paper's worst case: 0.4)
  double tdoa_sigma = 0.15;      ///< LOS noise of a TDoA difference (m)
  bool keep_twr = false;         ///< with tdoa: also write the SS-TWR ranges
  bool ultrasonic = false;       ///< ultrasonic beacons and ultrasonic.csv
  int ultrasonic_beacons = 4;    ///< paper: 4 transceivers
  double ultrasonic_hz = 10.0;   ///< pings per beacon per second (paper: 10 Hz)
  double ultrasonic_range = 8.0; ///< max range (m)
  double ultrasonic_sigma = 0.02;  ///< range noise (m)
  double sound_speed_error = 0.0;  ///< ranges (1 + e) times too long (temperature)
};

/// Simulates and writes the recording; returns the process exit code (0 ok,
/// 1 failure, the message already printed on stderr).
int runSim(const SimOptions& options);

/// Registers the `sim` subcommand; it exits through CLI::RuntimeError(code)
/// when the code is not 0. Link: rilo_sim, rilo_recording, CLI11::CLI11.
void addSimCommand(CLI::App& app);

}  // namespace rilo::tool
