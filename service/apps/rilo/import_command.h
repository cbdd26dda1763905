#pragma once
// `rilo import-util FLIGHT.csv --anchors SURVEY.txt --out DIR`: converts one
// flight of the UTIL dataset (UTIAS UWB TDoA; docs/util-dataset.md) into a
// recording folder (anchors, imu, tdoa, groundtruth, meta.yaml), checks the
// assumed units and TDoA sign against the Vicon ground truth and prints a
// summary. Exit codes: 0 written (or checked), 1 bad input (message names
// file:line: column), 2 the physics check contradicts the chosen options
// (nothing written unless --ignore-check).
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct ImportUtilOptions {
  std::string flight;              ///< flight CSV of the dataset
  std::string anchors;             ///< anchor survey text file (anchor_constN_survey.txt)
  std::string out;                 ///< recording folder to write (not needed with check_only)
  std::string tdoa_sign = "b-minus-a";
  std::string accel_unit = "g";
  std::string gyro_unit = "deg/s";
  std::string imu_clock = "gyro";
  std::string lever_arm;           ///< "x,y,z" (m, body frame); empty: the dataset's t_uv
  std::string gravity = "9.81";    ///< m/s^2
  std::string max_imu_gap_ms = "50";
  bool drop_unordered = false;
  bool overwrite = false;
  bool check_only = false;         ///< parse and check, write nothing
  bool ignore_check = false;       ///< write even if the check contradicts the options
};

/// Returns the process exit code (0, 1 or 2; messages on stdout/stderr).
int runImportUtil(const ImportUtilOptions& options);

/// Registers the `import-util` subcommand. Link: rilo_recording, CLI11::CLI11.
void addImportUtilCommand(CLI::App& app);

}  // namespace rilo::tool
