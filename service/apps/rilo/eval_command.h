#pragma once
// `rilo eval EST.tum REC`: accuracy of an estimated trajectory (TUM file, e.g.
// online.tum or smoothed.tum from `rilo replay`) against the ground truth of a
// recording folder (groundtruth.csv): APE (3D, horizontal, vertical; no
// alignment, the anchors fix the frame) and RPE over a time delta (1 s) and a
// travelled-distance delta (10 m). Definitions: evaluation/trajectory_metrics.h.
// Prints a table; --json FILE writes the same figures as JSON.
#include <string>

#include "evaluation/trajectory_metrics.h"

namespace CLI {
class App;
}

namespace rilo::tool {

struct EvalOptions {
  std::string estimate;    ///< TUM file
  std::string recording;   ///< recording folder with groundtruth.csv
  std::string json;        ///< JSON output file, empty: none
  double max_dt_ms = 50.0;      ///< association tolerance (ms)
  double rpe_delta_s = 1.0;     ///< time delta of the time-based RPE (s)
  double rpe_delta_m = 10.0;    ///< travelled-distance delta of the distance-based RPE (m)
  /// A numeric option that did not parse (set by the command line; runEval
  /// reports it with exit code 1 like any other bad input).
  std::string option_error;
};

/// The JSON document `--json` writes (paths as given in `options`).
std::string evaluationJson(const EvalOptions& options, const TrajectoryEvaluation& evaluation);

/// Returns the process exit code (0 ok, 1 bad input, the message on stderr).
int runEval(const EvalOptions& options);

/// Registers the `eval` subcommand. Link: rilo_evaluation, CLI11::CLI11.
void addEvalCommand(CLI::App& app);

}  // namespace rilo::tool
