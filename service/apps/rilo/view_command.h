#pragma once
// `rilo view [--config FILE] [--port N] [--bind ADDR]`: a live web page of a
// running rilod. Subscribes to the service's DDS topics (domain, interfaces
// and topic names from the same configuration the service runs, its anchors
// from that configuration's anchors file) and serves the page on
// http://ADDR:N/ (view/view_server.h): the anchors' floor plan, the pose with
// its covariance ellipse and heading, a trail, each anchor's newest range with
// its residual and NLOS verdict (rt/rilo/ranges), the status and its
// counters, pushed as they change. Prints the URL on stdout; runs until Ctrl-C.
#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace rilo::tool {

struct ViewOptions {
  std::string config = "config/rilod.yaml";  ///< the service's configuration
  std::uint16_t port = 8080;                 ///< 0: any free port (printed)
  std::string bind = "127.0.0.1";            ///< the page has no access control: loopback unless asked
  double seconds = 0.0;                      ///< stop after this long (0: until SIGINT/SIGTERM)
};

/// Returns the exit code: 0 stopped, 1 bad configuration, address or DDS set-up.
int runView(const ViewOptions& options);

/// Registers the `view` subcommand. Link: rilo_service, rilo_dds, cpp-httplib.
void addViewCommand(CLI::App& app);

}  // namespace rilo::tool
