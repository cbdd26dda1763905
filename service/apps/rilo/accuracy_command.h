#pragma once
// `rilo accuracy --out DIR [REC...] [--own-sims]`: the accuracy table the
// project judges its estimator by (docs/accuracy.md; evaluation/
// accuracy_table.h), in one command: the service's estimator over each
// recording as recorded and with the first-path column removed, at every
// rate of --rates, online and smoothed, with a before/after column against
// an earlier run's accuracy.csv (--compare). Writes DIR/accuracy.md and
// DIR/accuracy.csv; --own-sims first simulates the project's eleven sessions
// into DIR/recordings/.
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace rilo::tool {

struct AccuracyCommandOptions {
  std::vector<std::string> recordings;  ///< folders; each one's group is its parent folder's name
  std::string out;
  std::string config;   ///< rilod configuration (empty: the shipped one, built in)
  bool own_sims = false;
  double sim_seconds = 120.0;
  std::vector<double> rates_hz{40.0, 1.0};
  bool only_as_recorded = false;  ///< skip the first-path-removed variant
  int jobs = 2;
  std::string compare;  ///< an earlier accuracy.csv (empty: none)
};

/// Returns the process exit code (0: table written, even if some runs failed; 1: bad input or I/O failure).
int runAccuracyCommand(const AccuracyCommandOptions& options);

/// Registers the `accuracy` subcommand. Link: rilo_evaluation (with rilo_sim), CLI11.
void addAccuracyCommand(CLI::App& app);

}  // namespace rilo::tool
