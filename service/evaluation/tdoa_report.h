#pragma once
// The second system's evaluation (IMU-Ultrasonic-UWB paper, Table I and
// Sec. V): UWB TDoA (+ ultrasonic) recordings replayed by the sliding-window
// smoother (the paper's method), the EKF (the paper's baseline) and D-iSAM2
// (rilo's default), at full packet reception and at the paper's worst case of
// 40 %, as `rilo report --system tdoa` runs it. Every run is one
// replayRecording() (replay_run.h) with ReplaySettings::measurements and
// ::reception; runs are spread over worker threads (report.h parallelFor) and
// a run that throws is recorded, never aborts the table.
//
// Runs: every recording x every estimator x every reception (deduplicated).
// Figures per run: online and smoothed 3D APE (RMSE, mean, median, max),
// per-update time (mean, p99, max), updates, (re)initializations. The
// paper's claims the tables put beside ours: 12.3 cm RMS error, 38 % better
// than the EKF, 21 ms per iteration on a Jetson Nano, robust down to 40 %
// packet reception.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "evaluation/replay_run.h"
#include "evaluation/report.h"

namespace rilo {

struct TdoaReportOptions {
  /// Estimators (estimatorNames()); the table's rows in this order.
  std::vector<std::string> estimators{"sliding-window", "ekf", "d-isam2"};
  /// Packet receptions (0, 1]: 1 is the recording as recorded; the IMU-Ultrasonic-UWB paper's worst case is 0.4.
  std::vector<double> receptions{1.0, 0.4};
  MeasurementKinds measurements{false, true, true};  ///< IMU-Ultrasonic-UWB paper: TDoA and ultrasonic
  std::uint64_t reception_seed = 1;
  double lag_s = 5.0;                        ///< smoother lag / sliding window (s)
  std::optional<bool> dynamic_covariance;    ///< ReplaySettings::dynamic_covariance (unset: on when TDoA is used)
  std::string proposed = "sliding-window";   ///< the improvement row: proposed vs baseline
  std::string baseline = "ekf";
  double fail_mean_m = 10.0;                 ///< mean online APE above this: "Fail" (diverged)
  int jobs = 2;
  std::function<void(std::size_t done, std::size_t total)> progress;

  /// Throws std::invalid_argument naming the option.
  void validate() const;
};

struct TdoaRunSpec {
  std::size_t recording = 0;
  std::string estimator;
  double reception = 1.0;
};

struct TdoaRun {
  TdoaRunSpec spec;
  bool threw = false;
  std::string error;
  bool has_truth = false;
  PositionErrorStats ape_online, ape_smoothed;  ///< valid when has_truth and not threw
  std::size_t updates = 0;
  double update_mean_ms = 0.0, update_p99_ms = 0.0, update_max_ms = 0.0;
  std::uint64_t initializations = 0, reinitializations = 0;
  std::string last_failure;
  MeasurementCounts measurements;
  double data_s = 0.0, wall_s = 0.0;
  double tracked_share = 0.0;  ///< ReplayResult::online_tracked_share

  /// Threw, never produced a pose matched to the truth, or mean online APE
  /// above fail_mean_m (diverged). Needs has_truth (else false).
  bool failed(double fail_mean_m) const;
};

struct TdoaReportResults {
  TdoaReportOptions options;  ///< as run (progress cleared)
  std::vector<TdoaRun> runs;
  double wall_s = 0.0;

  const TdoaRun* find(std::size_t recording, const std::string& estimator, double reception) const;
};

/// Recording-major, then estimator, then reception.
std::vector<TdoaRunSpec> planTdoaRuns(const TdoaReportOptions& options, std::size_t recordings);

/// Runs them on options.jobs threads. Throws std::invalid_argument for bad
/// options or no recordings; a failing run is recorded in its TdoaRun.
TdoaReportResults runTdoaReport(const std::vector<ReportRecording>& recordings, const TdoaReportOptions& options);

/// Simulates a session as `rilo sim DIR --seed SEED --seconds SECONDS --plan
/// PLAN --tdoa --keep-twr --ultrasonic` does (its other defaults), into `dir`
/// (replacing a recording there). --keep-twr: the same session can also be
/// replayed with two-way ranges (ReplaySettings::measurements).
std::filesystem::path simulateTdoaReportRecording(std::uint64_t seed, double seconds, const std::filesystem::path& dir,
                                                  sim::OfficePlanKind plan = sim::OfficePlanKind::kHall);

/// (baseline - proposed) / baseline * 100, the IMU-Ultrasonic-UWB paper's "38 % improvement"; NaN
/// when either is not a number or the baseline is 0.
double improvementPercent(double proposed, double baseline);

}  // namespace rilo
