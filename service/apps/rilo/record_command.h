#pragma once
// `rilo record --config FILE --out DIR [--seconds S]`: records a hardware
// session (IMU and ranges from the configuration's sources.hardware section;
// anchors, IMU noise model and lever arm from the rest of the configuration)
// into the recording folder DIR, without running the estimator. The Recorder
// flushes every recording.flush_interval_ns (a crash loses at most that);
// SIGINT/SIGTERM or S seconds end the session cleanly. Prints progress once a
// second on stderr and the counts at the end. Exit code 0 on a clean stop, 1
// for a bad command line or configuration, or when a source failed / the disk
// write failed (the recording made so far is kept), 2 when a device cannot be
// opened (the message names the device path).
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct RecordCommandOptions {
  std::string config;   ///< rilod YAML configuration with sources.mode: hardware
  std::string out;      ///< recording folder to create (must not hold a recording)
  double seconds = 0.0; ///< stop after this long (0: until SIGINT/SIGTERM)
};

/// Returns the process exit code (see above); messages on stderr.
int runRecordCommand(const RecordCommandOptions& options);

/// Registers the `record` subcommand. Link: rilo_service, CLI11::CLI11.
void addRecordCommand(CLI::App& app);

}  // namespace rilo::tool
