#pragma once
// The evaluation matrix of the Ranging-IMU Fusion paper (Sec. VI) over a set of recordings, as
// `rilo report` runs it: every run is one replayRecording() (replay_run.h),
// runs are independent and spread over worker threads, and a run that throws
// is recorded (never aborts the matrix). No CLI and no files here except
// loading and simulating recordings; report_markdown.h writes the report.
//
// The runs (deduplicated; R = options.rates_hz, N = noises, S = smoothers):
//   Table I   every noise x every smoother at the full rate (all ranges)
//   Table II  every noise with the headline smoother at the low rate (1 Hz)
//   Table III every smoother with the headline noise at the full rate (subset of I)
//   Fig. 7    every noise with the headline smoother at every rate of R
//   Fig. 1    the headline configuration (headline noise and smoother, full
//             rate): its online trajectory is kept for the plots.
// The headline smoother is d-isam2 and the headline noise asymmetric when they
// are in the lists, else the first of each list.
//
// Rates: a rate >= full_rate_hz replays every range of the recording
// (range_hz = 0: "40 Hz (all ranges)"; the recordings are ranged at up to
// 40 Hz in total); a lower rate thins the ranges to that total rate
// (ReplaySettings::range_hz).
//
// Thread safety (checked for this runner): a Localizer owns all its state
// (smoother, CHOLMOD context with its workspace, noise models). The range
// losses are immutable and shared through the factory's cache, which a
// mutex guards (noise_model_factory.cpp); CHOLMOD's error handler finds its
// context through a thread_local. Recordings are shared read-only.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "estimation/tracking/range_imu_estimator.h"
#include "evaluation/trajectory_error.h"
#include "hal/recording/recording.h"
#include "sim/office_scenario.h"

namespace rilo {

/// One recording of the report, loaded once and shared read-only by the runs.
struct ReportRecording {
  std::string label;  ///< short unique name (folder name) for columns and file names
  std::string path;   ///< where it was read from (empty if built in memory)
  Recording data;

  double durationS() const;       ///< IMU span (s)
  double rangeRateHz() const;     ///< ranges per second over the IMU span
  std::size_t uwbAnchors() const;
};

/// Reads the recording folder `dir` (label: the folder name).
ReportRecording loadReportRecording(const std::filesystem::path& dir);

/// Makes the labels unique by appending "-2", "-3", ... to repeats (two
/// recordings in folders of the same name).
void makeLabelsUnique(std::vector<ReportRecording>& recordings);

/// Simulates an office session exactly as `rilo sim DIR --seed SEED --seconds
/// SECONDS --plan PLAN` does with its other options at their defaults (same
/// library call, sim::writeOfficeRecording) and writes it into `dir`,
/// replacing a recording already there. Returns the folder.
std::filesystem::path simulateReportRecording(std::uint64_t seed, double seconds, const std::filesystem::path& dir,
                                              sim::OfficePlanKind plan = sim::OfficePlanKind::kDefault);

struct ReportOptions {
  std::vector<double> rates_hz{1.0, 2.0, 4.0, 8.0, 20.0, 40.0};  ///< Fig. 7 (Hz)
  std::vector<std::string> smoothers{"d-isam2", "isam2", "dogleg"};
  std::vector<std::string> noises{"asymmetric", "gaussian", "huber", "cauchy"};
  double full_rate_hz = 40.0;  ///< Table I rate; rates >= it replay every range
  double low_rate_hz = 1.0;    ///< Table II rate
  double fail_mean_m = 10.0;   ///< a mean APE above this is "Fail" (paper, Table II)
  double lag_s = 5.0;          ///< fixed lag of every smoother (s)
  int jobs = 2;                ///< worker threads
  /// Called after every run with (runs done, runs in total), serialised (one
  /// call at a time, from the worker threads). May be empty.
  std::function<void(std::size_t done, std::size_t total)> progress;

  /// The --quick matrix: rates {1, 40}, smoothers {d-isam2, isam2}.
  void makeQuick();
  /// Throws std::invalid_argument naming the option (empty lists, unknown
  /// smoother or noise names, rates <= 0, jobs < 1, ...).
  void validate() const;
  std::string headlineSmoother() const;
  std::string headlineNoise() const;
};

struct ReportRunSpec {
  std::size_t recording = 0;  ///< index into the recordings
  std::string smoother;
  std::string noise;
  double rate_hz = 0.0;          ///< nominal total ranging rate (table label)
  bool all_ranges = false;       ///< replayed with every range (rate >= full_rate_hz)
  bool keep_trajectory = false;  ///< headline configuration: keep the online trajectory
};

struct ReportRun {
  ReportRunSpec spec;
  bool threw = false;
  std::string error;  ///< what() of the exception when threw
  bool has_truth = false;
  PositionErrorStats ape_online, ape_smoothed;  ///< valid when has_truth
  std::size_t updates = 0;
  double update_sum_ms = 0.0, update_mean_ms = 0.0, update_max_ms = 0.0;
  double data_s = 0.0, wall_s = 0.0, realtime_factor = 0.0;
  std::size_t ranges_used = 0;
  std::uint64_t initializations = 0, reinitializations = 0;
  std::string last_failure;  ///< why tracking last ended (Localizer), empty if never
  std::vector<RangeImuEstimator::TimedPose> online;  ///< keep_trajectory runs only

  /// "Fail" in the tables: threw, no online pose matched the ground truth,
  /// or mean online APE > fail_mean_m. Needs has_truth (else false).
  bool failed(double fail_mean_m) const;
};

struct ReportResults {
  ReportOptions options;  ///< as run (progress cleared)
  std::vector<ReportRun> runs;
  double wall_s = 0.0;

  /// The run of (recording, smoother, noise, rate), nullptr if not in the matrix.
  const ReportRun* find(std::size_t recording, const std::string& smoother, const std::string& noise,
                        double rate_hz) const;
};

/// The runs of the matrix for `recordings` recordings, in a fixed order
/// (recording-major). options must be valid.
std::vector<ReportRunSpec> planReportRuns(const ReportOptions& options, std::size_t recordings);

/// Runs the matrix on options.jobs threads. Never throws for a failing run
/// (it is recorded in its ReportRun); throws std::invalid_argument for bad
/// options or no recordings.
ReportResults runReport(const std::vector<ReportRecording>& recordings, const ReportOptions& options);

/// Runs fn(i) for i in [0, n) on `jobs` threads (each index once; the first
/// exception is rethrown after all threads stopped taking work). `progress`,
/// when set, gets (0, n) first and (done, n) after each fn that returned,
/// one call at a time.
void parallelFor(std::size_t n, int jobs, const std::function<void(std::size_t)>& fn,
                 const std::function<void(std::size_t done, std::size_t total)>& progress = {});

/// Online error over time against the ground truth (nearest truth pose in time
/// within 50 ms): one entry per matched pose.
struct ErrorSample {
  double t_s = 0.0;  ///< since the first IMU sample
  double error_3d_m = 0.0, error_horizontal_m = 0.0, error_vertical_m = 0.0;
};
std::vector<ErrorSample> errorOverTime(const std::vector<RangeImuEstimator::TimedPose>& poses,
                                       const Recording& recording);

}  // namespace rilo
