#pragma once
// `rilo replay REC --out DIR`: runs the online pipeline (Localizer:
// initialization, smoother, recovery) over a recording as fast as possible,
// deterministically, and writes what the service would have published
// (online.tum), the smoothed trajectory (smoothed.tum), per-update timing
// (timing.csv) and summary.json (APE against the ground truth if the
// recording has one, timing statistics, re-initializations).
#include <string>

#include "evaluation/replay_run.h"

namespace CLI {
class App;
}

namespace rilo::tool {

struct ReplayOptions {
  std::string recording;
  std::string out;
  /// rilod configuration to replay with (empty: the shipped one, built in).
  std::string config;
  /// Neither: the library's own estimator (LocalizerParams defaults, 0.15 m
  /// range sigma, 5 s lag) and the recording's device, as `rilo replay`
  /// without --config ran before session 31 (its figures in docs/ reproduce).
  bool library_defaults = false;
  ReplaySettings settings;
};

/// Which of the estimator's settings the command line gave itself.
struct GivenOptions {
  bool smoother = false, noise = false, lag = false;
};

/// Loads a rilod configuration into `settings` (ReplaySettings::
/// service_params), and its smoother, range noise model and lag unless the
/// caller gave them. Throws ConfigError naming the file, line and key.
void applyServiceConfig(const std::string& config_file, GivenOptions given, ReplaySettings& settings);
/// The same with the shipped configuration compiled into the tool
/// (shipped_config.h): `rilo replay`'s defaults.
void applyShippedConfig(GivenOptions given, ReplaySettings& settings);

/// Returns the process exit code (0 ok, 1 failure with the message on stderr).
int runReplay(const ReplayOptions& options);

/// Registers the `replay` subcommand. Link: rilo_evaluation.
void addReplayCommand(CLI::App& app);

}  // namespace rilo::tool
