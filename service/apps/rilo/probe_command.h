#pragma once
// `rilo probe --config FILE [--seconds S] [--json]`: bring-up check of the
// board. Opens the devices of the configuration's sources.hardware section,
// brings up the DWM3000 and the BMI263, prints what they report, ranges to
// every configured anchor and streams the IMU for S seconds, and prints the
// figures (rilod/hardware_probe.h). Exit code 0 when both devices work, 1 for
// a bad command line or configuration, 2 when a device cannot be opened or
// brought up (the message names the device path), 3 when the devices are up
// but nothing was measured (no anchor answered, no IMU sample).
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct ProbeCommandOptions {
  std::string config;    ///< rilod YAML configuration with sources.mode: hardware
  double seconds = 3.0;  ///< measurement time (s)
  bool json = false;     ///< the report as JSON on stdout
};

/// Returns the process exit code (see above); messages on stderr.
int runProbeCommand(const ProbeCommandOptions& options);

/// Registers the `probe` subcommand. Link: rilo_service, CLI11::CLI11.
void addProbeCommand(CLI::App& app);

}  // namespace rilo::tool
