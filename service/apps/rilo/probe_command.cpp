#include "probe_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "rilod/config.h"
#include "rilod/hardware_probe.h"
#include "rilod/hardware_sources.h"

namespace rilo::tool {
namespace {

std::atomic<bool> g_probe_interrupt{false};
extern "C" void onProbeSignal(int) { g_probe_interrupt.store(true); }

}  // namespace

int runProbeCommand(const ProbeCommandOptions& options) {
  HardwareSourceConfig hardware;
  try {
    if (!(options.seconds > 0.0 && options.seconds <= 3600.0)) {
      throw std::invalid_argument("--seconds must be in (0, 3600], got " + std::to_string(options.seconds));
    }
    hardware = requireHardwareSection(loadServiceConfig(options.config));
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }

  // Open each device on its own, so one missing node still lets the other be probed.
  LinuxHardware hw;
  UwbProbeTarget uwb;
  ImuProbeTarget imu;
  try {
    hw.openUwb(hardware.uwb, "rilo-probe-uwb");
    uwb.buses = hw.uwb();
  } catch (const std::exception& e) {
    uwb.open_error = e.what();
  }
  try {
    hw.openImu(hardware.imu, "rilo-probe-imu");
    imu.buses = hw.imu();
  } catch (const std::exception& e) {
    imu.open_error = e.what();
  }

  g_probe_interrupt.store(false);
  std::signal(SIGINT, onProbeSignal);
  std::signal(SIGTERM, onProbeSignal);
  ProbeOptions probe_options;
  probe_options.seconds = options.seconds;
  if (!options.json) {
    std::printf("rilo probe: %s, measuring %g s per device (Ctrl-C ends early)\n", options.config.c_str(),
                options.seconds);
    std::fflush(stdout);
  }
  ProbeReport report;
  try {
    report = runProbe(hardware, uwb, imu, probe_options, &g_probe_interrupt);
  } catch (const std::exception& e) {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    spdlog::error("{}", e.what());
    return 1;
  }
  std::signal(SIGINT, SIG_DFL);
  std::signal(SIGTERM, SIG_DFL);

  const std::string text = options.json ? probeReportJson(report) : probeReportText(report);
  std::fputs(text.c_str(), stdout);
  std::fflush(stdout);
  const int code = report.exitCode();
  if (code != 0) {
    for (const std::string& p : report.problems()) spdlog::error("{}", p);
  }
  return code;
}

void addProbeCommand(CLI::App& app) {
  auto options = std::make_shared<ProbeCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "probe", "Bring-up check: open the configured DWM3000 and BMI263, print their ids and status, range to each "
               "anchor and stream the IMU for a few seconds");
  cmd->add_option("--config", options->config, "rilod configuration with sources.mode: hardware")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("--seconds", options->seconds, "Measurement time per device (s)")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 3600.0));
  cmd->add_flag("--json", options->json, "Print the report as one JSON object");
  cmd->footer(
      "Ranges every configured anchor in turn at scheduler.range_rate_hz (no strongest-N selection) and prints per\n"
      "anchor: polls, ranges, success rate, mean and std of the range, RSSI and first-path power (CIA diagnostics,\n"
      "without the DGC term), clock offset and errors by kind. IMU: rate from the host timestamps, mean |accel|\n"
      "(9.81 m/s^2 at rest), mean gyro. Exit code 0 ok, 1 bad input, 2 a device could not be opened or brought up,\n"
      "3 nothing measured.");
  cmd->callback([options] {
    const int code = runProbeCommand(*options);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
