#include "replay_view.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include "dds/participant.h"
#include "dds/subscriber.h"
#include "evaluation/replay_run.h"
#include "hal/recording/recording_reader.h"
#include "rilod/service.h"
#include "rilod/service_setup.h"
#include "view/view_feed.h"
#include "view/view_page.h"
#include "view/view_server.h"
#include "view/view_state.h"

namespace rilo::tool {
namespace {

std::atomic<bool> g_replay_view_stop{false};
extern "C" void onReplayViewSignal(int) { g_replay_view_stop.store(true); }

}  // namespace

int runReplayView(const ReplayOptions& o, const ReplayViewOptions& v) {
  if (!(v.speed > 0.0 && v.speed <= 100.0)) throw std::invalid_argument("--view-speed must be in (0, 100]");
  const Recording rec = readRecording(o.recording);
  // A domain of its own on loopback, and topic names of this process: no
  // cross-talk with a running rilod or another replay's page.
  const std::uint32_t domain = 200 + static_cast<std::uint32_t>(::getpid() % 32);
  dds::TopicNames topics;
  const std::string suffix = "_view_" + std::to_string(::getpid());
  topics.odometry += suffix;
  topics.pose += suffix;
  topics.status += suffix;
  topics.ranges += suffix;
  topics.tf.clear();  // the page does not draw it

  ServiceOptions so;
  so.p_w_anchors = uwbAnchorsById(rec.anchors);
  so.localizer = localizerParamsFor(rec, o.settings);
  so.participant.domain_id = domain;
  so.participant.config_xml = dds::loopbackConfigXml();
  so.publisher.topics = topics;
  so.on_event = [](const std::string& event) { spdlog::info("{}", event); };
  so.on_fault = [](const SourceFault& f) { spdlog::warn("{}: {}", f.device, f.what); };
  ReplaySourceConfig source;
  source.path = o.recording;
  source.pace = ReplayPace::kRealTime;
  source.speed = v.speed;
  source.shift_to_now = true;
  std::vector<std::unique_ptr<SampleSource>> sources;
  sources.push_back(makeReplaySource(source));
  Service service(std::move(so), std::move(sources));

  ViewState state(rec.anchors);
  ViewServer server(state, std::string(viewPageHtml()));
  const int port = server.bind(v.bind, v.port);
  const dds::Participant participant(dds::ParticipantOptions{domain, dds::loopbackConfigXml()});
  dds::SubscriberOptions sub;
  sub.topics = topics;
  sub.odometry_depth = 256;  // faster than real time the samples come quicker
  sub.ranges = true;
  dds::Subscriber subscriber(participant, sub);

  spdlog::info("{} live at {}x (DDS domain {} on loopback); Ctrl-C stops", o.recording, v.speed, domain);
  std::printf("http://%s:%d/\n", v.bind.c_str(), port);
  std::fflush(stdout);

  g_replay_view_stop.store(false);
  std::signal(SIGINT, onReplayViewSignal);
  std::signal(SIGTERM, onReplayViewSignal);
  std::atomic<bool> service_done{false};
  int service_code = 0;
  std::thread runner([&] {
    service_code = service.run(g_replay_view_stop);
    service_done.store(true);
  });
  std::thread http([&server] { server.run(); });
  bool interrupted = false;
  {
    // However this scope ends (a DDS error throws): the service told to stop
    // and joined, the server stopped and joined.
    struct ServiceThread {
      std::thread& thread;
      ~ServiceThread() {
        g_replay_view_stop.store(true);
        if (thread.joinable()) thread.join();
      }
    } const joined_service{runner};
    const ServerThread joined_server{server, http};
    feedView(subscriber, state, [&] { return !service_done.load(); });
    interrupted = g_replay_view_stop.load();
  }
  spdlog::info("{}", interrupted ? "stopped" : "the recording ended");
  return service_code;
}

}  // namespace rilo::tool
