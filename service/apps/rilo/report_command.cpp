#include "report_command.h"
#include "rilo_version.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include "estimation/tracking/localizer.h"
#include "evaluation/report.h"
#include "evaluation/report_markdown.h"
#include "evaluation/tdoa_report.h"
#include "evaluation/tdoa_report_markdown.h"
#include "progress_bar.h"
#include "unsigned_option.h"

namespace rilo::tool {
namespace {

std::string commandLine(const ReportCommandOptions& o) {
  std::string cmd = "rilo report";
  for (const std::string& r : o.recordings) cmd += " " + r;
  cmd += " --out " + o.out;
  const auto join = [](const auto& items, auto&& text) {
    std::string s;
    for (const auto& item : items) s += (s.empty() ? "" : ",") + text(item);
    return s;
  };
  if (o.system == "tdoa") cmd += " --system tdoa";
  if (!o.sim_seeds.empty()) {
    cmd += " --sim-seeds " + join(o.sim_seeds, [](std::uint64_t v) { return std::to_string(v); });
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%g", o.sim_seconds);
    cmd += std::string(" --sim-seconds ") + seconds + " --sim-plan " + o.sim_plan;
  }
  const auto number = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%g", v);
    return std::string(buf);
  };
  if (o.system == "tdoa") {
    if (o.smoothers_given) cmd += " --smoothers " + join(o.smoothers, [](const std::string& s) { return s; });
    cmd += " --receptions " + join(o.receptions, number) + " --measurements " + o.measurements;
    cmd += " --reception-seed " + std::to_string(o.reception_seed);
    cmd += " --dynamic-covariance " + o.dynamic_covariance;
    cmd += " --lag " + number(o.lag_s) + " --jobs " + std::to_string(o.jobs);
    return cmd;
  }
  cmd += " --rates " + join(o.rates_hz, number);
  cmd += " --smoothers " + join(o.smoothers, [](const std::string& s) { return s; });
  cmd += " --noises " + join(o.noises, [](const std::string& s) { return s; });
  cmd += " --lag " + number(o.lag_s) + " --jobs " + std::to_string(o.jobs);
  return cmd;
}

sim::OfficePlanKind planKind(const std::string& name) {
  return name == "hall" ? sim::OfficePlanKind::kHall : name == "random" ? sim::OfficePlanKind::kRandom : sim::OfficePlanKind::kDefault;
}

/// `rilo report --system tdoa`: the IMU-Ultrasonic-UWB paper's table (evaluation/tdoa_report.h).
int runTdoaReportCommand(const ReportCommandOptions& o) {
  TdoaReportOptions options;
  if (o.smoothers_given) options.estimators = o.smoothers;
  options.receptions = o.receptions;
  options.measurements = measurementKindsFromString(o.measurements);
  options.reception_seed = o.reception_seed;
  options.lag_s = o.lag_s;
  if (o.dynamic_covariance != "auto") options.dynamic_covariance = o.dynamic_covariance == "on";
  options.jobs = o.jobs;
  options.validate();  // before minutes of simulation

  const std::filesystem::path out(o.out);
  if (std::filesystem::exists(out) && !std::filesystem::is_directory(out)) {
    throw std::invalid_argument(o.out + " exists and is not a folder");
  }
  std::filesystem::create_directories(out);
  std::vector<ReportRecording> recordings;
  for (const std::string& dir : o.recordings) {
    if (!std::filesystem::is_directory(dir)) throw std::invalid_argument("REC " + dir + " is not a folder");
    recordings.push_back(loadReportRecording(dir));
  }
  if (!o.sim_seeds.empty()) {
    std::vector<std::filesystem::path> dirs;
    for (std::uint64_t seed : o.sim_seeds) {
      dirs.push_back(out / "recordings" / ("sim-tdoa-" + o.sim_plan + "-seed-" + std::to_string(seed)));
    }
    ProgressBar bar("report", "simulated sessions");
    parallelFor(
        dirs.size(), o.jobs,
        [&](std::size_t i) { simulateTdoaReportRecording(o.sim_seeds[i], o.sim_seconds, dirs[i], planKind(o.sim_plan)); },
        [&bar](std::size_t done, std::size_t total) { bar(done, total); });
    for (const std::filesystem::path& dir : dirs) recordings.push_back(loadReportRecording(dir));
  }
  makeLabelsUnique(recordings);

  TdoaReportResults results;
  {
    ProgressBar bar("report", "runs");
    options.progress = [&bar](std::size_t done, std::size_t total) { bar(done, total); };
    results = runTdoaReport(recordings, options);
  }
  writeTdoaReport(out, recordings, results, currentReportHeader(commandLine(o), "rilo " RILO_VERSION_TEXT));
  std::size_t failed = 0, threw = 0;
  for (const TdoaRun& r : results.runs) {
    if (r.failed(options.fail_mean_m)) ++failed;
    if (r.threw) ++threw;
  }
  std::printf("rilo report --system tdoa: %zu runs on %zu recordings in %.1f s (%zu failed, %zu threw)\n",
              results.runs.size(), recordings.size(), results.wall_s, failed, threw);
  std::printf("  wrote %s/{%s,%s}\n", o.out.c_str(), kReportMarkdownFile, kReportCsvFile);
  return 0;
}

}  // namespace

int runReportCommand(const ReportCommandOptions& o) {
  try {
    if (o.recordings.empty() && o.sim_seeds.empty()) {
      throw std::invalid_argument("give recordings (REC...) or --sim-seeds");
    }
    if (o.system == "tdoa") return runTdoaReportCommand(o);
    ReportOptions options;
    options.rates_hz = o.rates_hz;
    options.smoothers = o.smoothers;
    options.noises = o.noises;
    options.jobs = o.jobs;
    options.lag_s = o.lag_s;
    options.validate();  // before minutes of simulation

    const std::filesystem::path out(o.out);
    if (std::filesystem::exists(out) && !std::filesystem::is_directory(out)) {
      throw std::invalid_argument(o.out + " exists and is not a folder");
    }
    std::filesystem::create_directories(out);

    std::vector<ReportRecording> recordings;
    for (const std::string& dir : o.recordings) {
      if (!std::filesystem::is_directory(dir)) throw std::invalid_argument("REC " + dir + " is not a folder");
      recordings.push_back(loadReportRecording(dir));
    }
    if (!o.sim_seeds.empty()) {
      std::vector<std::filesystem::path> dirs;
      for (std::uint64_t seed : o.sim_seeds) dirs.push_back(out / "recordings" / ("sim-seed-" + std::to_string(seed)));
      {
        ProgressBar bar("report", "simulated sessions");
        parallelFor(
            dirs.size(), o.jobs,
            [&](std::size_t i) { simulateReportRecording(o.sim_seeds[i], o.sim_seconds, dirs[i], planKind(o.sim_plan)); },
            [&bar](std::size_t done, std::size_t total) { bar(done, total); });
      }
      for (const std::filesystem::path& dir : dirs) recordings.push_back(loadReportRecording(dir));
    }
    makeLabelsUnique(recordings);

    ReportResults results;
    {
      ProgressBar bar("report", "runs");
      options.progress = [&bar](std::size_t done, std::size_t total) { bar(done, total); };
      results = runReport(recordings, options);
    }
    writeReport(out, recordings, results, currentReportHeader(commandLine(o), "rilo " RILO_VERSION_TEXT));

    std::size_t failed = 0, threw = 0;
    for (const ReportRun& r : results.runs) {
      if (r.failed(options.fail_mean_m)) ++failed;
      if (r.threw) ++threw;
    }
    std::printf("rilo report: %zu runs on %zu recordings in %.1f s (%zu failed, %zu threw)\n", results.runs.size(),
                recordings.size(), results.wall_s, failed, threw);
    std::printf("  wrote %s/{%s,%s,%s/}\n", o.out.c_str(), kReportMarkdownFile, kReportCsvFile, kReportFiguresDir);
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addReportCommand(CLI::App& app) {
  auto o = std::make_shared<ReportCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "report",
      "Run the evaluation matrix of the paper (Tables I-III, Fig. 7, Fig. 1) over recordings and write a Markdown "
      "report with tables, SVG plots and results.csv");
  cmd->add_option("REC", o->recordings, "Recording folders (ground truth needed for the error tables)")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", o->out, "Output folder: report.md, results.csv, figures/ (and recordings/ with --sim-seeds)")
      ->required();
  CLI::Option* rates =
      cmd->add_option("--rates", o->rates_hz,
                      "Total ranging rates of Fig. 7 (Hz, comma separated, at most 40; 40 replays every range; "
                      "Table I always runs at 40 Hz and Table II at 1 Hz)")
          ->delimiter(',')
          ->capture_default_str()
          ->check(CLI::Range(0.01, 40.0));
  CLI::Option* smoothers =
      cmd->add_option("--smoothers", o->smoothers,
                      "Estimators of Tables I and III (comma separated; d-isam2, else the first, is the estimator "
                      "of Table II, Fig. 7 and Fig. 1)")
          ->delimiter(',')
          ->capture_default_str()
          ->check(CLI::IsMember(estimatorNames()));
  cmd->add_option("--noises", o->noises,
                  "Range noise models (comma separated; asymmetric, else the first, is the headline model of Fig. 1 "
                  "and Table III)")
      ->delimiter(',')
      ->capture_default_str()
      ->check(CLI::IsMember({"asymmetric", "gaussian", "huber", "cauchy", "asymmetric-half-cauchy"}));
  cmd->add_option("--jobs", o->jobs, "Runs in parallel (worker threads; per-update times are less reliable above 1)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_flag("--quick", o->quick,
                "Fast look: rates 1,40 and smoothers d-isam2,isam2 (unless --rates / --smoothers are given)");
  cmd->add_option("--sim-seeds", o->sim_seeds,
                  "Simulate office sessions with these seeds (as `rilo sim --seed N`) into OUT/recordings/ and "
                  "evaluate them too (comma separated)")
      ->delimiter(',')->check(cli::notNegative());
  cmd->add_option("--sim-seconds", o->sim_seconds, "Duration of each simulated session (s)")
      ->capture_default_str()
      ->check(CLI::Range(3.0, 36000.0));
  cmd->add_option("--sim-plan", o->sim_plan, "Plan of the simulated sessions (as rilo sim --plan)")
      ->capture_default_str()
      ->check(CLI::IsMember({"default", "random", "hall"}));
  cmd->add_option("--lag", o->lag_s, "Fixed lag of every smoother (s)")->capture_default_str()->check(CLI::Range(0.5, 600.0));
  cmd->add_option("--system", o->system,
                  "twr: the Ranging-IMU Fusion paper's matrix (two-way ranges); tdoa: the IMU-Ultrasonic-UWB "
                  "paper's table (TDoA + ultrasonic: sliding window vs EKF vs D-iSAM2, full and reduced packet "
                  "reception)")
      ->capture_default_str()
      ->check(CLI::IsMember({"twr", "tdoa"}));
  cmd->add_option("--receptions", o->receptions,
                  "--system tdoa: packet receptions to run (comma separated, in (0, 1]; the highest is Table I's)")
      ->delimiter(',')
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1.0));
  cmd->add_option("--measurements", o->measurements,
                  "--system tdoa: measurement kinds fed (range,tdoa,ultrasonic; comma separated)")
      ->capture_default_str();
  cmd->add_option("--reception-seed", o->reception_seed, "--system tdoa: seed of the dropped packets")
      ->capture_default_str()
      ->check(cli::notNegative());
  cmd->add_option("--dynamic-covariance", o->dynamic_covariance,
                  "--system tdoa: per-link TDoA/ultrasonic sigmas from their residuals: auto (on for every estimator "
                  "when TDoA is used), on (every estimator) or off")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "on", "off"}));
  cmd->callback([o, rates, smoothers] {
    ReportCommandOptions run = *o;
    run.smoothers_given = smoothers->count() > 0;
    if (run.quick) {
      ReportOptions quick;
      quick.makeQuick();
      if (rates->count() == 0) run.rates_hz = quick.rates_hz;
      if (smoothers->count() == 0) run.smoothers = quick.smoothers;
    }
    const int rc = runReportCommand(run);
    if (rc != 0) throw CLI::RuntimeError(rc);
  });
}

}  // namespace rilo::tool
