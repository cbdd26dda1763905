// rilod: the localization service. Reads its YAML configuration, brings up
// the sources (replay of a recording, or the DWM3000 and BMI263 drivers),
// DDS and the threads, tells systemd when it is ready, and runs until the
// data ends or SIGTERM/SIGINT.
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <memory>

#include "hal/replay/replay_source.h"
#include "rilod/config.h"
#include "rilod/hardware_sources.h"
#include "rilod/notify.h"
#include "rilod/recorder.h"
#include "rilod/recorder_config.h"
#include "rilod/service.h"
#include "runtime/realtime.h"

namespace {

std::atomic<bool> g_stop{false};
extern "C" void onSignal(int) { g_stop.store(true); }

const char* stateName(rilo::TrackingState s) {
  switch (s) {
    case rilo::TrackingState::kInitializing: return "initializing";
    case rilo::TrackingState::kTracking: return "tracking";
    case rilo::TrackingState::kDegraded: return "degraded";
    case rilo::TrackingState::kLost: return "lost";
  }
  return "?";
}

/// A source whose samples are also written to the recorder.
class RecordedSource final : public rilo::SampleSource {
 public:
  RecordedSource(std::unique_ptr<rilo::SampleSource> inner, rilo::SampleSink& recorder)
      : inner_(std::move(inner)), recorder_(recorder) {}
  rilo::SourceEnd run(rilo::SampleSink& sink, const std::atomic<bool>& stop) override {
    rilo::TeeSink tee(sink, recorder_);
    return inner_->run(tee, stop);
  }
  std::string describe() const override { return inner_->describe() + " (recorded)"; }

 private:
  std::unique_ptr<rilo::SampleSource> inner_;
  rilo::SampleSink& recorder_;
};

int runService(const rilo::ServiceConfig& cfg, double max_seconds) {
  for (const std::string& w : rilo::applyProcessRealtime(cfg.realtime.process)) spdlog::warn("real-time: {}", w);

  // Sources.
  std::vector<std::unique_ptr<rilo::SampleSource>> sources;
  rilo::LinuxHardware hw;  // buses live as long as the sources using them
  if (cfg.sources.mode == rilo::SourceMode::kReplay) {
    rilo::ReplayOptions ro;
    ro.pacing = cfg.sources.replay.pace == rilo::ReplayPace::kRealTime ? rilo::ReplayOptions::Pacing::kRealTime
                                                                       : rilo::ReplayOptions::Pacing::kAsFastAsPossible;
    ro.speed = cfg.sources.replay.speed;
    ro.shift_to_now = cfg.sources.replay.shift_to_now && ro.pacing == rilo::ReplayOptions::Pacing::kRealTime;
    sources.push_back(std::make_unique<rilo::ReplaySource>(cfg.sources.replay.path, ro));
  } else {
    hw.openAll(cfg.sources.hardware, "rilod");
    sources = rilo::makeHardwareSources(cfg.sources.hardware, hw.uwb(), hw.imu());
  }
  for (const auto& s : sources) spdlog::info("source: {}", s->describe());

  const std::vector<rilo::Vec3> p_w_anchors = rilo::uwbAnchorsById(cfg.anchors);

  // Recording (optional): a tee in front of every source.
  std::unique_ptr<rilo::Recorder> recorder;
  if (cfg.recording.enabled) {
    const rilo::RecordingSetup setup = rilo::recordingSetup(cfg);
    const rilo::RecorderOptions options = rilo::recorderOptions(cfg);
    const auto dir = rilo::newRecordingDirectory(cfg.recording.directory);
    recorder = std::make_unique<rilo::Recorder>(dir, setup, sources.size(), options);
    for (std::size_t i = 0; i < sources.size(); ++i) {
      sources[i] = std::make_unique<RecordedSource>(std::move(sources[i]), recorder->channel(i));
    }
    spdlog::info("recording to {} (flushed every {} ms)", dir.string(), cfg.recording.flush_interval_ns / 1'000'000);
  }

  rilo::ServiceOptions so;
  so.p_w_anchors = p_w_anchors;
  so.localizer.graph = cfg.estimator.graph;
  for (const rilo::Anchor& a : cfg.anchors) {  // ultrasonic beacons by id, for ultrasonic ranges
    if (a.kind != rilo::AnchorKind::kUltrasonic) continue;
    auto& beacons = so.localizer.graph.p_w_ultrasonic;
    if (beacons.size() <= a.id) beacons.resize(a.id + 1, rilo::Vec3::Constant(1e6));
    beacons[a.id] = a.p_w_anchor;
  }
  so.localizer.smoother = cfg.estimator.smoother;
  so.localizer.stream = cfg.estimator.stream;
  so.localizer.init.window_s = cfg.estimator.init_window_s;
  so.localizer.height_band = cfg.estimator.height_band;
  so.localizer.vertical_speed_sigma_m_s = cfg.estimator.vertical_speed_sigma_m_s;
  if (so.localizer.height_band.enabled && !so.localizer.height_band.plausibleFor(p_w_anchors)) {
    spdlog::warn("estimator.height_band: the anchors do not look mounted 1-6 m above a floor at z = {:.2f} m; the band is off "
                 "(set estimator.height_band.floor_z_m to the floor height in the anchors' frame)",
                 so.localizer.height_band.floor_z_m);
  }
  so.participant.domain_id = cfg.dds.domain_id;
  if (cfg.dds.loopback_only) so.participant.config_xml = rilo::dds::loopbackConfigXml();
  if (!cfg.dds.cyclone_config_file.empty()) so.participant.config_xml = "file://" + cfg.dds.cyclone_config_file.string();
  so.publisher.topics = cfg.dds.topics;
  so.publisher.frames = cfg.dds.frames;
  so.queue_capacity = cfg.realtime.queue_capacity;
  so.backpressure = cfg.sources.mode == rilo::SourceMode::kReplay && cfg.sources.replay.pace == rilo::ReplayPace::kAsFastAsPossible;
  so.status_period_s = static_cast<double>(cfg.status.period_ns) * 1e-9;
  so.sensor_silence_s = static_cast<double>(cfg.status.imu_timeout_ns) * 1e-9;
  so.on_status = [](const rilo::ServiceStatus& s) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "%s: imu %llu, ranges %llu, odometry %llu; update mean %.2f ms, max %.2f ms; faults %llu, overflows %llu, re-inits %llu",
                  stateName(s.state), static_cast<unsigned long long>(s.imu_samples),
                  static_cast<unsigned long long>(s.range_samples), static_cast<unsigned long long>(s.published_odometry),
                  s.mean_update_ms, s.max_update_ms, static_cast<unsigned long long>(s.sensor_faults),
                  static_cast<unsigned long long>(s.queue_overflows), static_cast<unsigned long long>(s.reinitializations));
    spdlog::info("{}", line);
    rilo::notify::status(line);
  };
  so.on_fault = [](const rilo::SourceFault& f) {
    if (f.fatal) {
      spdlog::error("{}: {} (source stopped)", f.device, f.what);
    } else {
      spdlog::warn("{}: {}", f.device, f.what);
    }
  };
  so.on_event = [](const std::string& e) { spdlog::info("{}", e); };
  so.on_thread_start = [&cfg](const std::string& role, std::thread& t) {
    const rilo::ThreadRealtimeSettings& rt = role == "estimator" ? cfg.realtime.estimator
                                             : role == "publisher" ? cfg.realtime.publisher
                                             : cfg.sources.mode == rilo::SourceMode::kReplay ? cfg.realtime.replay_source
                                             : role == "source 0" ? cfg.realtime.uwb_source : cfg.realtime.imu_source;
    for (const std::string& w : rilo::applyThreadRealtime(t, rt)) spdlog::warn("real-time: {}", w);
  };

  rilo::Service service(std::move(so), std::move(sources));
  spdlog::info("DDS domain {}: {}, {}, {}", cfg.dds.domain_id, cfg.dds.topics.odometry, cfg.dds.topics.pose, cfg.dds.topics.status);
  rilo::notify::readyWithStatus("sources and DDS up, initializing");
  std::unique_ptr<rilo::notify::WatchdogPinger> watchdog;
  if (cfg.watchdog.enabled) {
    watchdog = rilo::notify::startWatchdogIfRequested(service.estimatorHeartbeat(), cfg.watchdog.heartbeat_timeout_ns,
                                                      cfg.watchdog.startup_grace_ns);
  }

  std::atomic<bool> stop{false};
  std::thread timer;
  if (max_seconds > 0.0) {
    timer = std::thread([&stop, max_seconds] {
      const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(max_seconds);
      while (!stop.load() && !g_stop.load() && std::chrono::steady_clock::now() < end) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
      }
      g_stop.store(true);
    });
  }
  // The service polls `g_stop` itself (set from the signal handler).
  const int code = service.run(g_stop);
  stop.store(true);
  if (timer.joinable()) timer.join();
  rilo::notify::stopping();
  if (watchdog) watchdog->stop();
  if (recorder) {
    recorder->close();
    const auto c = recorder->counters();
    spdlog::info("recording closed: {} samples written, {} dropped", c.written, c.dropped_full + c.dropped_failed);
  }
  const rilo::ServiceStatus last = service.status();
  spdlog::info("stopped ({}): {} IMU samples, {} ranges, {} odometry messages; smoother update mean {:.2f} ms, max {:.2f} ms",
               stateName(last.state), last.imu_samples, last.range_samples, last.published_odometry, last.mean_update_ms,
               last.max_update_ms);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rilod: UWB + IMU localization service (publishes the pose over DDS)"};
  std::string config_path;
  double max_seconds = 0.0;
  app.add_option("--config", config_path, "YAML configuration (see config/README.md)")->required()->check(CLI::ExistingFile);
  app.add_option("--duration", max_seconds, "Stop after this many seconds (0: until the data ends or SIGTERM)")
      ->check(CLI::NonNegativeNumber);
  CLI11_PARSE(app, argc, argv);

  spdlog::set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    const rilo::ServiceConfig cfg = rilo::loadServiceConfig(config_path);
    spdlog::info("rilod starting with {}", cfg.file.string());
    return runService(cfg, max_seconds);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    rilo::notify::status(std::string("failed: ") + e.what());
    return 2;
  }
}
