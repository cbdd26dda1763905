#include "accuracy_command.h"
#include "rilo_version.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

#include "evaluation/accuracy_table.h"
#include "evaluation/report.h"
#include "evaluation/report_markdown.h"
#include "progress_bar.h"
#include "replay_command.h"

namespace rilo::tool {
namespace {

constexpr const char* kAccuracyMarkdownFile = "accuracy.md";
constexpr const char* kAccuracyCsvFile = "accuracy.csv";

/// One session --own-sims simulates, named as in docs/accuracy.md (office1-4, rnd1-4, hall1-3).
struct OwnSim {
  sim::OfficePlanKind plan;
  const char* name;
  unsigned seed;
};

const std::vector<OwnSim>& ownSims() {
  using sim::OfficePlanKind;
  static const std::vector<OwnSim> kSims = {
      {OfficePlanKind::kDefault, "office", 1}, {OfficePlanKind::kDefault, "office", 2},
      {OfficePlanKind::kDefault, "office", 3}, {OfficePlanKind::kDefault, "office", 4},
      {OfficePlanKind::kRandom, "rnd", 1},     {OfficePlanKind::kRandom, "rnd", 2},
      {OfficePlanKind::kRandom, "rnd", 3},     {OfficePlanKind::kRandom, "rnd", 4},
      {OfficePlanKind::kHall, "hall", 1},      {OfficePlanKind::kHall, "hall", 2},
      {OfficePlanKind::kHall, "hall", 3}};
  return kSims;
}

std::string number(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

std::string commandLine(const AccuracyCommandOptions& o) {
  std::string cmd = "rilo accuracy";
  for (const std::string& r : o.recordings) cmd += " " + r;
  cmd += " --out " + o.out;
  if (!o.config.empty()) cmd += " --config " + o.config;
  if (o.own_sims) cmd += " --own-sims --sim-seconds " + number(o.sim_seconds);
  std::string rates;
  for (double r : o.rates_hz) rates += (rates.empty() ? "" : ",") + number(r);
  cmd += " --rates " + rates;
  if (o.only_as_recorded) cmd += " --only-as-recorded";
  if (!o.compare.empty()) cmd += " --compare " + o.compare;
  return cmd + " --jobs " + std::to_string(o.jobs);
}

std::string headerText(const ReportHeader& h, const std::string& config) {
  std::string text = "# Accuracy: " + config + "\n\n";
  text += "- command: `" + h.command + "`\n";
  if (!h.version.empty()) text += "- build: " + h.version + "\n";
  text += "- made: " + h.date + " on " + h.machine + (h.cpu_model.empty() ? "" : ", " + h.cpu_model) + " (" +
          std::to_string(h.cpus) + " CPUs)";
  return text;
}

}  // namespace

int runAccuracyCommand(const AccuracyCommandOptions& o) {
  try {
    if (o.recordings.empty() && !o.own_sims) throw std::invalid_argument("give recordings (REC...) or --own-sims");
    AccuracyOptions options;
    options.rates_hz = o.rates_hz;
    options.without_first_path = !o.only_as_recorded;
    options.jobs = o.jobs;
    options.validate();  // before minutes of simulation
    ReplaySettings settings;
    if (o.config.empty()) {
      applyShippedConfig({}, settings);
    } else {
      applyServiceConfig(o.config, {}, settings);
    }
    std::vector<AccuracyRow> before;
    if (!o.compare.empty()) before = readAccuracyCsv(o.compare);  // before the runs: a bad file fails at once

    const std::filesystem::path out(o.out);
    if (std::filesystem::exists(out) && !std::filesystem::is_directory(out)) {
      throw std::invalid_argument(o.out + " exists and is not a folder");
    }
    std::filesystem::create_directories(out);

    // The recordings and their groups; labels made unique before they name rows.
    std::vector<ReportRecording> loaded;
    std::vector<std::string> groups;
    if (o.own_sims) {
      const std::vector<OwnSim>& sims = ownSims();
      std::vector<std::filesystem::path> dirs;
      for (const OwnSim& s : sims) dirs.push_back(out / "recordings" / (s.name + std::to_string(s.seed)));
      {
        ProgressBar bar("accuracy", "simulated sessions");
        parallelFor(
            sims.size(), o.jobs,
            [&](std::size_t i) { simulateReportRecording(sims[i].seed, o.sim_seconds, dirs[i], sims[i].plan); },
            [&bar](std::size_t done, std::size_t total) { bar(done, total); });
      }
      for (const std::filesystem::path& dir : dirs) {
        loaded.push_back(loadReportRecording(dir));
        groups.push_back("own");
      }
    }
    for (const std::string& dir : o.recordings) {
      if (!std::filesystem::is_directory(dir)) throw std::invalid_argument("REC " + dir + " is not a folder");
      const std::filesystem::path path = std::filesystem::absolute(dir).lexically_normal();
      const std::filesystem::path folder = path.has_filename() ? path : path.parent_path();  // "f11/" -> "f11"
      const std::string group = folder.parent_path().filename().string();
      loaded.push_back(loadReportRecording(folder));
      groups.push_back(group.empty() ? "given" : group);
    }
    makeLabelsUnique(loaded);  // one row per set and recording: the same folder name twice gets "-2"
    std::vector<AccuracyRecording> recordings;
    for (std::size_t i = 0; i < loaded.size(); ++i) recordings.push_back({groups[i], std::move(loaded[i])});

    std::vector<AccuracyRow> rows;
    {
      ProgressBar bar("accuracy", "runs");
      options.progress = [&bar](std::size_t done, std::size_t total) { bar(done, total); };
      rows = runAccuracyTable(recordings, settings, options);
    }
    writeAccuracyCsv(out / kAccuracyCsvFile, rows);
    const ReportHeader header = currentReportHeader(commandLine(o), "rilo " RILO_VERSION_TEXT);
    const std::string md = accuracyMarkdown(rows, o.compare.empty() ? nullptr : &before,
                                            headerText(header, o.config.empty() ? "config/rilod.yaml (built in)" : o.config));
    {
      std::ofstream file(out / kAccuracyMarkdownFile);
      file << md;
      file.flush();
      if (!file) throw std::runtime_error("cannot write " + (out / kAccuracyMarkdownFile).string());
    }
    std::size_t failed = 0, never = 0;
    for (const AccuracyRow& r : rows) {
      if (!r.error.empty()) {
        ++failed;
        spdlog::warn("{} {}: {}", r.set, r.recording, r.error);
      } else if (!r.started) {
        ++never;
      }
    }
    std::printf("rilo accuracy: %zu runs on %zu recordings (%zu never started, %zu failed)\n", rows.size(),
                recordings.size(), never, failed);
    std::printf("  wrote %s/{%s,%s}\n", o.out.c_str(), kAccuracyMarkdownFile, kAccuracyCsvFile);
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addAccuracyCommand(CLI::App& app) {
  auto o = std::make_shared<AccuracyCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "accuracy",
      "The accuracy table of docs/accuracy.md in one command: the service's estimator over recordings as recorded and "
      "with the first-path column removed, at full rate and ~1 Hz, online and smoothed, before/after an earlier run");
  cmd->add_option("REC", o->recordings,
                  "Recording folders with ground truth; each is grouped under its parent folder's name")
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--out", o->out, "Output folder: accuracy.md, accuracy.csv (and recordings/ with --own-sims)")
      ->required();
  cmd->add_option("--config", o->config, "rilod configuration whose estimator runs (default: config/rilod.yaml, built in)")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--own-sims", o->own_sims,
                "Simulate and include the project's eleven sessions (rilo sim --seed 1-4, --plan random --seed 1-4, "
                "--plan hall --seed 1-3)");
  cmd->add_option("--sim-seconds", o->sim_seconds, "Duration of each simulated session (s)")
      ->capture_default_str()
      ->check(CLI::Range(3.0, 36000.0));
  cmd->add_option("--rates", o->rates_hz,
                  "Total ranging rates (Hz, comma separated; 40 and above replay every range, lower ones thin them)")
      ->delimiter(',')
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1000.0));
  cmd->add_flag("--only-as-recorded", o->only_as_recorded,
                "Leave out the variant with the first-path column removed");
  cmd->add_option("--compare", o->compare, "An earlier run's accuracy.csv: each figure as before -> after")
      ->check(CLI::ExistingFile);
  cmd->add_option("--jobs", o->jobs, "Runs in parallel (worker threads)")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->callback([o] {
    const int code = runAccuracyCommand(*o);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
