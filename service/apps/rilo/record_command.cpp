#include "record_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "rilod/config.h"
#include "rilod/hardware_sources.h"
#include "rilod/record_session.h"
#include "rilod/recorder.h"
#include "rilod/recorder_config.h"

namespace rilo::tool {
namespace {

std::atomic<bool> g_record_stop{false};
extern "C" void onRecordSignal(int) { g_record_stop.store(true); }

unsigned long long ull(std::uint64_t v) { return static_cast<unsigned long long>(v); }

void printTotals(const std::vector<SourceTally>& sources, const RecorderCounters& c, double seconds, FILE* out) {
  std::uint64_t imu = 0, ranges = 0, faults = 0;
  for (const SourceTally& s : sources) {
    imu += s.imu;
    ranges += s.ranges;
    faults += s.faults;
  }
  std::fprintf(out, "%.1f s: %llu IMU samples, %llu ranges, %llu written, %llu dropped, %llu rejected, %llu faults\n",
               seconds, ull(imu), ull(ranges), ull(c.written), ull(c.dropped_full + c.dropped_failed), ull(c.rejected),
               ull(faults));
}

}  // namespace

int runRecordCommand(const RecordCommandOptions& options) {
  ServiceConfig config;
  try {
    if (!(options.seconds >= 0.0 && options.seconds <= 1e7)) {
      throw std::invalid_argument("--seconds must be in [0, 1e7], got " + std::to_string(options.seconds));
    }
    if (options.out.empty()) throw std::invalid_argument("--out must name the recording folder");
    config = loadServiceConfig(options.config);
    (void)requireHardwareSection(config);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
  const HardwareSourceConfig& hardware = config.sources.hardware;

  LinuxHardware hw;
  try {
    hw.openAll(hardware, "rilo-record");
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 2;
  }
  std::vector<std::unique_ptr<SampleSource>> sources;
  std::unique_ptr<Recorder> recorder;
  const RecorderOptions recorder_options = recorderOptions(config);
  try {
    sources = makeHardwareSources(hardware, hw.uwb(), hw.imu());
    RecordingSetup setup = recordingSetup(config);
    setup.meta.name = std::filesystem::path(options.out).filename().string();
    setup.meta.description = "hardware session recorded by rilo record, config " + config.file.string();
    recorder = std::make_unique<Recorder>(options.out, setup, sources.size(), recorder_options);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }

  spdlog::info("recording to {} (flushed every {} ms){}", options.out, recorder_options.flush_interval_ns / 1'000'000,
               options.seconds > 0.0 ? "" : "; Ctrl-C or SIGTERM stops");
  for (const auto& s : sources) spdlog::info("source: {}", s->describe());

  g_record_stop.store(false);
  std::signal(SIGINT, onRecordSignal);
  std::signal(SIGTERM, onRecordSignal);
  // --seconds: a timer that sets the same flag as the signals.
  std::atomic<bool> timer_done{false};
  std::thread timer;
  if (options.seconds > 0.0) {
    timer = std::thread([&timer_done, seconds = options.seconds] {
      const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
      while (!timer_done.load() && !g_record_stop.load() && std::chrono::steady_clock::now() < end) {
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
      g_record_stop.store(true);
    });
  }

  std::vector<SampleSource*> raw;
  for (const auto& s : sources) raw.push_back(s.get());
  RecordSessionOptions session_options;
  session_options.progress_period_ns = 1'000'000'000;
  RecordSessionCallbacks callbacks;
  callbacks.on_fault = [](const SourceFault& f) {
    if (f.fatal) {
      spdlog::error("{}: {}", f.device, f.what);
    } else {
      spdlog::warn("{}: {}", f.device, f.what);
    }
  };
  callbacks.on_note = [](const SourceNote& n) { spdlog::info("{}: {}", n.device, n.what); };
  const auto t0 = std::chrono::steady_clock::now();
  callbacks.on_progress = [t0](const std::vector<SourceTally>& tallies, const RecorderCounters& c) {
    printTotals(tallies, c, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), stderr);
  };

  RecordSessionResult result;
  int code = 0;
  try {
    result = runRecordSession(raw, *recorder, g_record_stop, session_options, callbacks);
    code = result.exitCode();
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    code = 1;
  }
  timer_done.store(true);
  if (timer.joinable()) timer.join();
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);
  recorder->close();

  std::printf("rilo record: %s\n", options.out.c_str());
  printTotals(result.sources, result.recorder, result.seconds, stdout);
  for (const SourceTally& s : result.sources) {
    const char* end = s.end == SourceEnd::kFailed ? "FAILED" : s.end == SourceEnd::kEndOfData ? "end of data" : "stopped";
    std::printf("  %s: %llu IMU, %llu ranges, %llu faults, %s%s%s\n", s.name.c_str(), ull(s.imu), ull(s.ranges),
                ull(s.faults), end, s.last_fault.empty() ? "" : "; last fault: ", s.last_fault.c_str());
  }
  if (!result.recorder_error.empty()) {
    std::printf("  recorder: %s%s\n", result.recorder_failed ? "FAILED: " : "", result.recorder_error.c_str());
  }
  std::fflush(stdout);
  return code;
}

void addRecordCommand(CLI::App& app) {
  auto options = std::make_shared<RecordCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "record", "Record a hardware session (IMU + ranges from the configured DWM3000 and BMI263) into a recording folder");
  cmd->add_option("--config", options->config, "rilod configuration with sources.mode: hardware")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--out", options->out, "Recording folder to create (must not hold a recording yet)")->required();
  cmd->add_option("--seconds", options->seconds, "Stop after this long (s; 0: until SIGINT/SIGTERM)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e7));
  cmd->footer(
      "Writes meta.yaml (IMU noise model and rate, lever arm, ranging ss-twr), anchors.csv from the configuration,\n"
      "imu.csv and range.csv as samples arrive, flushed every recording.flush_interval_s (a crash loses at most\n"
      "that). Replay it with `rilo replay DIR` or rilod's replay source. Exit code 0 clean stop, 1 bad input or a\n"
      "source / disk failure (the recording so far is kept), 2 a device could not be opened.");
  cmd->callback([options] {
    const int code = runRecordCommand(*options);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
