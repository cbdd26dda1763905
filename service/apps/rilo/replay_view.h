#pragma once
// `rilo replay REC --view`: the recording replayed live (real time, stamps
// shifted to now) through the service itself (rilod's Service, with the
// estimator the replay's flags and configuration give), which publishes over
// DDS on a private loopback domain, and `rilo view`'s page over it: the same
// page a running rilod shows, for a recording. Writes no files.
#include <cstdint>
#include <string>

#include "replay_command.h"

namespace rilo::tool {

struct ReplayViewOptions {
  bool enabled = false;             ///< --view
  std::uint16_t port = 8080;        ///< 0: any free port (printed)
  std::string bind = "127.0.0.1";
  double speed = 1.0;               ///< recording seconds per wall-clock second
};

/// Returns the exit code (0 when the recording ended or on Ctrl-C).
int runReplayView(const ReplayOptions& replay, const ReplayViewOptions& view);

}  // namespace rilo::tool
