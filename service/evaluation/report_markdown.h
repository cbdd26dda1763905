#pragma once
// Writes the results of the evaluation matrix (report.h) as a Markdown report
// in the layout of the Ranging-IMU Fusion paper's Sec. VI, a CSV with one row per run, and SVG
// figures (svg_plot.h):
//   DIR/report.md     header (date, machine, version, recordings, settings),
//                     Table I (online and smoothed), Table II, Fig. 7 (+ its
//                     data), Table III, the headline configuration's
//                     horizontal/vertical APE and re-initializations, Fig. 1
//                     per recording, failed runs
//   DIR/results.csv   one row per run (kResultsCsvHeader)
//   DIR/figures/      fig7_ape_vs_rate.svg, fig1_<label>_top.svg,
//                     fig1_<label>_error.svg
// Cells: "mean/max" in metres with two decimals; within 5 % of the best of
// their column (mean and max separately, among runs that did not fail) they
// are bold, as in the paper; "Fail" when ReportRun::failed (threw, no
// estimate, or mean > the threshold); "n/a" without ground truth.
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/report.h"

namespace rilo {

struct ReportHeader {
  std::string date;          ///< when the report was made (local time, ISO 8601)
  std::string machine;       ///< uname: system, release, architecture, host
  std::string cpu_model;     ///< empty if unknown
  unsigned cpus = 0;         ///< processors available to the process (nproc)
  std::string version;       ///< the build that made the report (rilo --version); empty if unknown
  std::string command;       ///< command line that made the report
};

/// The header for a report made now by this process (uname, nproc,
/// /proc/cpuinfo; `version`: the build's, RILO_VERSION_TEXT, given by the
/// program, not `git describe` of whatever directory it runs in): never
/// fails, unknown fields stay empty.
ReportHeader currentReportHeader(const std::string& command, const std::string& version);

inline constexpr const char* kReportMarkdownFile = "report.md";
inline constexpr const char* kReportCsvFile = "results.csv";
inline constexpr const char* kReportFiguresDir = "figures";
inline constexpr const char* kResultsCsvHeader =
    "recording,smoother,noise,rate_hz,all_ranges,status,ape_online_mean_m,ape_online_max_m,ape_smoothed_mean_m,"
    "ape_smoothed_max_m,ape_online_horizontal_mean_m,ape_online_vertical_mean_m,ape_online_vertical_bias_m,"
    "update_mean_ms,update_max_ms,updates,realtime_factor,initializations,reinitializations,ranges_used,wall_s,error,"
    "last_failure";

/// results.csv. status: ok | fail (no estimate or mean APE above the
/// threshold) | error (the run threw; message in `error`) | no-truth. Numbers
/// are empty where unknown.
std::string resultsCsv(const std::vector<ReportRecording>& recordings, const ReportResults& results);

/// report.md; figures are referenced under kReportFiguresDir with the names
/// writeReport gives them.
std::string reportMarkdown(const std::vector<ReportRecording>& recordings, const ReportResults& results,
                           const ReportHeader& header);

/// Writes report.md, results.csv and the figures into `dir` (created).
/// Throws std::runtime_error if a file cannot be written.
void writeReport(const std::filesystem::path& dir, const std::vector<ReportRecording>& recordings,
                 const ReportResults& results, const ReportHeader& header);

/// File-name-safe form of a recording label ([A-Za-z0-9._-], others '_').
std::string fileSafeLabel(const std::string& label);

}  // namespace rilo
