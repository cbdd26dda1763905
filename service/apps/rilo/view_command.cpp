#include "view_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <thread>

#include "dds/participant.h"
#include "dds/subscriber.h"
#include "rilod/config.h"
#include "rilod/service_setup.h"
#include "unsigned_option.h"
#include "view/view_feed.h"
#include "view/view_page.h"
#include "view/view_server.h"
#include "view/view_state.h"

namespace rilo::tool {
namespace {

std::atomic<bool> g_view_stop{false};
extern "C" void onViewSignal(int) { g_view_stop.store(true); }

}  // namespace

int runView(const ViewOptions& o) {
  try {
    if (!(o.seconds >= 0.0)) throw std::invalid_argument("--seconds must be >= 0");
    const ServiceConfig cfg = loadServiceConfig(o.config);
    const ServiceOptions so = serviceOptions(cfg);
    ViewState state(cfg.anchors);
    ViewServer server(state, std::string(viewPageHtml()));
    const int port = server.bind(o.bind, o.port);

    const dds::Participant participant(so.participant);
    dds::SubscriberOptions sub;
    sub.topics = so.publisher.topics;
    sub.odometry_depth = 64;
    sub.ranges = !sub.topics.ranges.empty();  // a service configured without it: the page shows no ranges  // the page shows the newest; a slow take loses only older ones
    dds::Subscriber subscriber(participant, sub);

    spdlog::info("domain {}, {} anchors from {}; Ctrl-C stops", cfg.dds.domain_id, cfg.anchors.size(), o.config);
    std::printf("http://%s:%d/\n", o.bind.c_str(), port);  // stdout: the one result, for scripts
    std::fflush(stdout);

    g_view_stop.store(false);
    std::signal(SIGINT, onViewSignal);
    std::signal(SIGTERM, onViewSignal);
    std::thread http([&server] { server.run(); });
    // Stop and join the server however this scope ends (a DDS error throws).
    const ServerThread joined{server, http};
    const auto t0 = std::chrono::steady_clock::now();
    feedView(subscriber, state, [&] {
      return !g_view_stop.load() &&
             (o.seconds <= 0.0 || std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() < o.seconds);
    });
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addViewCommand(CLI::App& app) {
  auto options = std::make_shared<ViewOptions>();
  CLI::App* cmd = app.add_subcommand(
      "view", "Serve a live web page of a running rilod: anchors, pose with covariance and heading, trail, status");
  cmd->add_option("--config", options->config, "The service's configuration (DDS domain, topics, anchors)")
      ->capture_default_str()
      ->check(CLI::ExistingFile);
  cmd->add_option("--port", options->port, "TCP port of the page (0: any free port)")
      ->capture_default_str()
      ->check(cli::notNegative());
  cmd->add_option("--bind", options->bind, "Address to serve on (the page has no access control)")->capture_default_str();
  cmd->add_option("--seconds", options->seconds, "Stop after this long (s; 0: until SIGINT/SIGTERM)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->callback([options] {
    if (const int code = runView(*options); code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
