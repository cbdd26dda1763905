#pragma once
// `rilo report REC... --out DIR`: runs the evaluation matrix of the Ranging-IMU Fusion paper
// Sec. VI (Tables I-III, Fig. 7, Fig. 1; evaluation/report.h) over recordings,
// on worker threads with a progress bar on stderr, and writes DIR/report.md,
// DIR/results.csv and DIR/figures/*.svg (evaluation/report_markdown.h).
// With --sim-seeds it first simulates office sessions (the library behind
// `rilo sim`) into DIR/recordings/.
// --system tdoa runs the second system's table instead (IMU-Ultrasonic-UWB paper, Table I:
// sliding window vs EKF vs D-iSAM2 on TDoA + ultrasonic recordings, at full
// and reduced packet reception; evaluation/tdoa_report.h), with --sim-seeds
// simulating TDoA + ultrasonic sessions (SS-TWR kept).
#include <cstdint>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace rilo::tool {

struct ReportCommandOptions {
  std::vector<std::string> recordings;
  std::string out;
  std::vector<double> rates_hz{1.0, 2.0, 4.0, 8.0, 20.0, 40.0};
  std::vector<std::string> smoothers{"d-isam2", "isam2", "dogleg"};
  std::vector<std::string> noises{"asymmetric", "gaussian", "huber", "cauchy"};
  int jobs = 2;
  bool quick = false;  ///< applied by addReportCommand to the lists not given explicitly
  std::vector<std::uint64_t> sim_seeds;
  double sim_seconds = 120.0;  ///< duration of each simulated session
  std::string sim_plan = "default";  ///< default | random | hall (as rilo sim --plan)
  double lag_s = 5.0;
  // --system tdoa
  std::string system = "twr";  ///< twr (Ranging-IMU Fusion paper's matrix) | tdoa (IMU-Ultrasonic-UWB paper's table)
  bool smoothers_given = false;  ///< --smoothers given: the TDoA table's estimators
  std::vector<double> receptions{1.0, 0.4};
  std::string measurements = "tdoa,ultrasonic";
  std::uint64_t reception_seed = 1;
  std::string dynamic_covariance = "auto";  ///< auto | on | off (ReplaySettings::dynamic_covariance)
};

/// Returns the process exit code (0: report written, even if some runs
/// failed; 1: bad input or I/O failure, the message on stderr).
int runReportCommand(const ReportCommandOptions& options);

/// Registers the `report` subcommand. Link: rilo_evaluation (with rilo_sim), CLI11.
void addReportCommand(CLI::App& app);

}  // namespace rilo::tool
