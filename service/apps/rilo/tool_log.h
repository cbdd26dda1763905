#pragma once
// Where the rilo tools' messages go: through spdlog, as rilod's do. Under
// systemd (stderr is the journal's stream) straight to journald with each
// message's priority; elsewhere to stderr as
//   rilo <command>: message            (info)
//   rilo <command>: warning: message
//   rilo <command>: error: message
// Results (tables, reports, --json) stay on stdout; live progress bars stay
// on the terminal (they are not log lines).
#include <string>

namespace rilo::tool {

/// Makes the logger of `command` ("replay", "listen"; empty: the bare tool)
/// spdlog's default logger.
void setUpToolLogging(const std::string& command);

}  // namespace rilo::tool
