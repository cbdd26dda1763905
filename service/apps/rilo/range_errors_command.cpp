#include "range_errors_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>

#include "evaluation/range_errors.h"
#include "evaluation/report_text.h"
#include "hal/recording/recording_reader.h"

namespace rilo::tool {
namespace {

// "+0.123" / "12.5 %", "-" where there is no figure.
std::string signedCell(double v, int decimals) { return std::isfinite(v) ? strf("%+.*f", decimals, v) : "-"; }
std::string percentCell(double share) { return std::isfinite(share) ? strf("%.1f %%", 100.0 * share) : "-"; }

void printRow(const std::string& label, const RangeErrorStats& s) {
  std::printf("| %s | %zu | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n", label.c_str(), s.count,
              signedCell(s.mean_m, 3).c_str(), signedCell(s.p1_m, 3).c_str(), signedCell(s.p5_m, 3).c_str(),
              signedCell(s.median_m, 3).c_str(), signedCell(s.p95_m, 3).c_str(), signedCell(s.p99_m, 3).c_str(),
              percentCell(s.short_share).c_str(), percentCell(s.long_share).c_str(),
              signedCell(s.radial_slope_s, 3).c_str(), signedCell(s.radial_correlation, 2).c_str());
}

void printRecording(const std::string& path, const RangeErrors& r, double threshold_m) {
  std::printf("\n## %s\n\n", path.c_str());
  std::printf("%zu ranges with ground truth", r.errors.size());
  std::printf("; left out: %zu outside it", r.without_truth);
  // The reader refuses unknown anchors and tags in files: only recordings built in code have them.
  if (r.unknown_anchor > 0) std::printf(", %zu to unknown anchors", r.unknown_anchor);
  if (r.unknown_tag > 0) std::printf(", %zu from unknown tags", r.unknown_tag);
  if (r.non_finite > 0) std::printf(", %zu not finite", r.non_finite);
  std::printf("\n\n");
  std::printf("| ranges | count | mean (m) | p1 | p5 | median | p95 | p99 | short < -%.2f | long > +%.2f | "
              "slope on radial speed (s) | correlation |\n",
              threshold_m, threshold_m);
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  printRow("all", summarizeRangeErrors(r.errors, threshold_m));
  std::vector<RangeError> los, nlos;
  std::map<std::uint32_t, std::vector<RangeError>> by_anchor;
  for (const RangeError& e : r.errors) {
    if (e.los == 1) los.push_back(e);
    if (e.los == 0) nlos.push_back(e);
    by_anchor[e.anchor_id].push_back(e);
  }
  if (!los.empty() || !nlos.empty()) {
    printRow("labelled LOS", summarizeRangeErrors(los, threshold_m));
    printRow("labelled NLOS", summarizeRangeErrors(nlos, threshold_m));
  }
  for (const auto& [id, errors] : by_anchor) {
    printRow("anchor " + std::to_string(id), summarizeRangeErrors(errors, threshold_m));
  }
}

}  // namespace

int runRangeErrorsCommand(const RangeErrorsCommandOptions& o) {
  try {
    if (o.recordings.empty()) throw std::invalid_argument("no recording given");
    if (!(o.threshold_m >= 0.0) || !std::isfinite(o.threshold_m)) {
      throw std::invalid_argument("--threshold must be finite and >= 0, got " + std::to_string(o.threshold_m));
    }
    RangeErrorOptions options;
    options.truth_shift_s = o.truth_shift_s;
    // Written beside the target and renamed at the end: a failure on a later
    // recording leaves no partial file under the name asked for.
    const std::string csv_tmp = o.csv + ".tmp";
    std::ofstream csv;
    if (!o.csv.empty()) {
      csv.open(csv_tmp);
      if (!csv) throw std::runtime_error("cannot write " + csv_tmp);
      csv << "recording,t_ns,anchor_id,tag_id,range_m,true_m,error_m,radial_speed_m_s,los\n";
    }
    std::printf("# Range errors against the ground truth (range - true distance to the antenna)\n");
    if (o.truth_shift_s != 0.0) std::printf("\nThe truth taken %+.3f s before each range's stamp.\n", o.truth_shift_s);
    for (const std::string& path : o.recordings) {
      ReadReport read_report;
      const Recording recording = readRecording(path, &read_report);
      for (const ReadWarning& w : read_report.warnings) spdlog::warn("{}", w.message);
      RangeErrors errors;
      try {
        errors = rangeErrors(recording, options);
      } catch (const std::invalid_argument& e) {
        throw std::invalid_argument(path + ": " + e.what());
      }
      printRecording(path, errors, o.threshold_m);
      if (!csv.is_open()) continue;
      const std::string field = csvField(path);
      for (const RangeError& e : errors.errors) {
        char numbers[160];
        std::snprintf(numbers, sizeof numbers, "%lld,%u,%u,%.9g,%.9g,%.9g,%.9g,%d\n", static_cast<long long>(e.t_ns),
                      e.anchor_id, e.tag_id, e.range_m, e.true_m, e.error_m, e.radial_speed_m_s, e.los);
        csv << field << ',' << numbers;
      }
    }
    if (csv.is_open()) {
      csv.close();
      if (!csv) throw std::runtime_error("writing " + csv_tmp + " failed");
      std::filesystem::rename(csv_tmp, o.csv);
    }
    return 0;
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    if (!o.csv.empty()) {
      std::error_code ignored;
      std::filesystem::remove(o.csv + ".tmp", ignored);
    }
    return 1;
  }
}

void addRangeErrorsCommand(CLI::App& app) {
  auto o = std::make_shared<RangeErrorsCommandOptions>();
  CLI::App* cmd = app.add_subcommand(
      "range-errors",
      "How a recording's ranges err against its ground truth: quantiles, shares too short and too long, slope on "
      "the radial speed; all, per LOS label (simulators) and per anchor");
  cmd->add_option("REC", o->recordings, "Recording folders with groundtruth.csv")
      ->required()
      ->check(CLI::ExistingDirectory);
  cmd->add_option("--csv", o->csv, "Also write every range's error to this CSV file");
  cmd->add_option("--threshold", o->threshold_m, "An error beyond +-this counts as long / short (m)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--truth-shift", o->truth_shift_s,
                  "Take the true distance this long before each range's stamp (s): were the ranges measured before "
                  "their stamps? The right shift takes the slope on the radial speed to 0")
      ->capture_default_str()
      ->check(CLI::Range(-60.0, 60.0));
  cmd->callback([o] {
    const int code = runRangeErrorsCommand(*o);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
