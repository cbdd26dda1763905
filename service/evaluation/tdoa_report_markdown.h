#pragma once
// Writes the TDoA system evaluation (tdoa_report.h) like the IMU-Ultrasonic-UWB paper's Table I:
//   DIR/report.md    header (date, machine, version, command), recordings,
//                    settings; Table I online and smoothed 3D RMSE (cm) per
//                    recording and over all of them (at the highest
//                    reception of the options), one row per estimator,
//                    and the improvement of the proposed estimator (sliding
//                    window) over the baseline (EKF) in %; per estimator the
//                    online and smoothed RMSE / mean / max and the per-update
//                    time mean / p99; one table per reduced reception (the
//                    IMU-Ultrasonic-UWB paper's 40 % row) with the runs that diverged; failed runs.
//   DIR/results.csv  one row per run (kTdoaResultsCsvHeader)
// "All" pools the recordings: RMSE over every matched pose of every
// recording (sqrt of the count-weighted mean square), mean likewise, max the
// largest. A failed run (TdoaRun::failed: threw, never tracked, or diverged)
// shows "Fail" and is left out of the pooled figures, which then say so.
// results.csv's dynamic_covariance: 1 on for every estimator, 0 off, auto
// the default (every estimator on when TDoA is used).
#include <filesystem>
#include <string>
#include <vector>

#include "evaluation/report_markdown.h"
#include "evaluation/tdoa_report.h"

namespace rilo {

inline constexpr const char* kTdoaResultsCsvHeader =
    "recording,estimator,reception,measurements,dynamic_covariance,status,online_rmse_m,online_mean_m,online_median_m,"
    "online_max_m,smoothed_rmse_m,smoothed_mean_m,smoothed_max_m,update_mean_ms,update_p99_ms,update_max_ms,updates,"
    "initializations,reinitializations,range_used,range_dropped,tdoa_used,tdoa_dropped,ultrasonic_used,wall_s,error,"
    "last_failure";

std::string tdoaResultsCsv(const std::vector<ReportRecording>& recordings, const TdoaReportResults& results);
std::string tdoaReportMarkdown(const std::vector<ReportRecording>& recordings, const TdoaReportResults& results,
                               const ReportHeader& header);
/// Writes report.md and results.csv into `dir` (created). Throws
/// std::runtime_error if a file cannot be written.
void writeTdoaReport(const std::filesystem::path& dir, const std::vector<ReportRecording>& recordings,
                     const TdoaReportResults& results, const ReportHeader& header);

}  // namespace rilo
