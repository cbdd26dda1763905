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

#include "rilo_version.h"
#include "rilod/config.h"
#include "rilod/hardware_sources.h"
#include "rilod/logging.h"
#include "rilod/notify.h"
#include "rilod/recorder.h"
#include "rilod/recorder_config.h"
#include "rilod/service.h"
#include "rilod/service_setup.h"
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
    if (!cfg.sources.replay.faults.empty()) {
      spdlog::warn("fault injection is on (sources.replay.faults): the replayed data is damaged on purpose");
    }
    sources.push_back(rilo::makeReplaySource(cfg.sources.replay));
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

  rilo::ServiceOptions so = rilo::serviceOptions(cfg);
  if (so.localizer.height_band.enabled && !so.localizer.height_band.plausibleFor(p_w_anchors)) {
    spdlog::warn("estimator.height_band: the anchors do not look mounted 1-6 m above a floor at z = {:.2f} m; the band is off "
                 "(set estimator.height_band.floor_z_m to the floor height in the anchors' frame)",
                 so.localizer.height_band.floor_z_m);
  }
  so.on_status = [](const rilo::ServiceStatus& s) {
    auto u = [](std::uint64_t v) { return static_cast<unsigned long long>(v); };
    char tdoa[96] = "";  // the IMU-Ultrasonic-UWB paper's system only: a two-way line stays as it was
    if (s.tdoa_samples > 0 || s.ultrasonic_samples > 0) {
      std::snprintf(tdoa, sizeof tdoa, ", tdoa %llu (deep NLOS %llu), ultrasonic %llu", u(s.tdoa_samples),
                    u(s.deep_nlos_tdoa_rows), u(s.ultrasonic_samples));
    }
    char screen[128] = "";  // only when the estimator's screen dropped something
    if (s.out_of_bounds_samples + s.beyond_full_scale_samples + s.far_future_samples + s.time_jumps > 0) {
      std::snprintf(screen, sizeof screen, "; screened out-of-bounds %llu, beyond-full-scale %llu, far-future %llu, time jumps %llu",
                    u(s.out_of_bounds_samples), u(s.beyond_full_scale_samples), u(s.far_future_samples), u(s.time_jumps));
    }
    char line[760];
    std::snprintf(line, sizeof line,
                  "%s: imu %llu, ranges %llu (rejected %llu)%s, odometry %llu (latency max %.2f ms); update mean %.2f ms, "
                  "p99 %.2f ms, max %.2f ms; faults %llu, overflows %llu, re-inits %llu; dropped non-finite %llu, duplicate %llu, "
                  "out-of-order %llu%s; gaps imu %llu, ranging %llu%s%s",
                  stateName(s.state), u(s.imu_samples), u(s.range_samples), u(s.rejected_ranges), tdoa,
                  u(s.published_odometry), s.odometry_latency_ms, s.mean_update_ms, s.p99_update_ms, s.max_update_ms,
                  u(s.sensor_faults), u(s.queue_overflows), u(s.reinitializations), u(s.non_finite_samples),
                  u(s.duplicate_samples), u(s.out_of_order_samples), screen, u(s.imu_gaps), u(s.ranging_gaps),
                  s.reason[0] != '\0' ? " -- " : "", s.reason.data());
    // The status line is the log's rate limit: once per status period.
    if (s.state == rilo::TrackingState::kTracking || s.state == rilo::TrackingState::kInitializing) {
      spdlog::info("{}", line);
    } else {
      spdlog::warn("{}", line);
    }
    char short_line[256];
    std::snprintf(short_line, sizeof short_line, "%s: odometry %llu, re-inits %llu%s%s", stateName(s.state),
                  u(s.published_odometry), u(s.reinitializations), s.reason[0] != '\0' ? "; " : "", s.reason.data());
    rilo::notify::status(short_line);
  };
  so.on_fault = [](const rilo::SourceFault& f) {
    if (f.fatal) {
      spdlog::error("{}: {} (source stopped)", f.device, f.what);
    } else {
      spdlog::warn("{}: {}", f.device, f.what);
    }
  };
  so.on_event = [](const std::string& e) { spdlog::info("{}", e); };
  so.on_note = [](const rilo::SourceNote& n) { spdlog::info("{}: {}", n.device, n.what); };
  // STOPPING=1 as soon as the stop request is seen (issue 37: it went out
  // only after shutdown, so systemd waited without knowing).
  std::atomic<bool> stopping_sent{false};
  so.on_stop_requested = [&stopping_sent] {
    spdlog::info("stop requested: shutting down");
    rilo::notify::stopping();
    stopping_sent.store(true);
  };
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
    // Every real-time thread must beat for a ping: sources, estimator, publisher, status.
    watchdog = rilo::notify::startWatchdogIfRequested(service.watchedThreads(), cfg.watchdog.heartbeat_timeout_ns,
                                                      cfg.watchdog.startup_grace_ns);
    if (watchdog) {
      spdlog::info("systemd watchdog: pinging every {} ms while {} threads beat", watchdog->period().count() / 1000,
                   service.watchedThreads().size());
    }
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
  if (!stopping_sent.load()) rilo::notify::stopping();  // the data ended: no stop request came
  if (watchdog) {
    if (watchdog->stalled()) spdlog::warn("systemd watchdog: '{}' had stopped beating", watchdog->stalledThread());
    watchdog->stop();
  }
  if (recorder) {
    recorder->close();
    const auto c = recorder->counters();
    spdlog::info("recording closed: {} samples written, {} dropped", c.written, c.dropped_full + c.dropped_failed);
  }
  const rilo::ServiceStatus last = service.status();
  spdlog::info(
      "stopped ({}): {} IMU samples, {} ranges, {} odometry messages; smoother update mean {:.2f} ms, p99 {:.2f} ms, "
      "max {:.2f} ms; queues high water {} (estimator) / {} (publisher) samples",
      stateName(last.state), last.imu_samples, last.range_samples, last.published_odometry, last.mean_update_ms,
      last.p99_update_ms, last.max_update_ms, last.estimator_queue_high_water, last.publisher_queue_high_water);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"rilod: UWB + IMU localization service (publishes the pose over DDS)"};
  std::string config_path;
  double max_seconds = 0.0;
  app.set_version_flag("--version", "rilod " RILO_VERSION_TEXT);
  app.add_option("--config", config_path, "YAML configuration (see config/README.md)")->required()->check(CLI::ExistingFile);
  app.add_option("--seconds", max_seconds, "Stop after this many seconds (0: until the data ends or SIGTERM)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  CLI11_PARSE(app, argc, argv);

  rilo::setUpServiceLogging();  // journald with priorities under systemd, else the console
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);
  try {
    const rilo::ServiceConfig cfg = rilo::loadServiceConfig(config_path);
    spdlog::info("rilod {} starting with {}", RILO_VERSION_TEXT, cfg.file.string());
    return runService(cfg, max_seconds);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    rilo::notify::status(std::string("failed: ") + e.what());
    return 2;
  }
}
