#pragma once
// The accuracy table the project judges its estimator by (docs/accuracy.md):
// one estimator (the service's configuration) over groups of recordings,
// each as recorded and, where it carries the receiver's first-path power,
// with that column removed (receivers that report the RX level only), at
// the full ranging rate and thinned to lower ones; online (what rilod
// publishes) and smoothed error, height offset, first published position
// and full state, share of the recording tracked. `rilo accuracy` writes it,
// with a before/after column against an earlier run's CSV.
//
// Every run is one replayRecording() (replay_run.h), spread over worker
// threads (report.h parallelFor); a run that throws is recorded, never
// aborts the table.
#include <cstddef>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "evaluation/replay_run.h"
#include "evaluation/report.h"

namespace rilo {

/// The same recording as a receiver without the first-path power would have
/// written it: every range's fp_power_dbm unknown (NaN), the rest unchanged.
Recording withoutFirstPath(const Recording& rec);
/// Whether any range of `rec` carries a first-path power.
bool hasFirstPath(const Recording& rec);

struct AccuracyOptions {
  /// Ranging rates (Hz). A rate >= full_rate_hz replays every range ("all"),
  /// a lower one thins them to that total rate (ReplaySettings::range_hz).
  std::vector<double> rates_hz{40.0, 1.0};
  double full_rate_hz = 40.0;
  /// Also run each recording that has a first-path column without it.
  bool without_first_path = true;
  int jobs = 2;
  /// (runs done, runs in total), one call at a time. May be empty.
  std::function<void(std::size_t, std::size_t)> progress;

  /// Throws std::invalid_argument naming the option.
  void validate() const;
};

/// One recording of a group (the group names the set: "own", "foreign", ...).
struct AccuracyRecording {
  std::string group;
  ReportRecording recording;
};

/// One run's figures, as accuracy.csv holds them. NaN / nullopt where the
/// run has none (no pose, no ground truth, no update, a run that threw).
struct AccuracyRow {
  static constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  std::string set;        ///< group, rate and variant: "own, all ranges, first path removed", "own, 1 Hz"
  std::string recording;  ///< label
  bool started = false;   ///< published at least one pose
  double online_mean_m = kNone, online_max_m = kNone, smoothed_mean_m = kNone;
  double height_offset_m = kNone;  ///< mean signed vertical error of the online poses (m)
  std::optional<double> first_position_s, first_full_state_s;
  double tracked_share = 0.0;
  double update_mean_ms = kNone, update_max_ms = kNone;
  /// Shares of the published poses inside their covariance's 95 % region,
  /// horizontally and vertically (covariance_consistency.h; 0.95 when honest).
  double covariance_horizontal_in_95 = kNone, covariance_vertical_in_95 = kNone;
  std::string error;  ///< what() when the run threw (then started is false)
};

/// Runs every recording in every variant. Throws std::invalid_argument for
/// bad options or no recordings; a failing run is a row with `error`.
/// options.progress gets (0, total) first (report.h parallelFor).
std::vector<AccuracyRow> runAccuracyTable(const std::vector<AccuracyRecording>& recordings,
                                          const ReplaySettings& settings, const AccuracyOptions& options);

/// accuracy.csv: a header line and one line per row. Throws std::runtime_error when it cannot be written.
void writeAccuracyCsv(const std::filesystem::path& file, const std::vector<AccuracyRow>& rows);
/// Reads what writeAccuracyCsv wrote, and the files of before session 44
/// (without the covariance columns: NaN there). Throws std::runtime_error
/// naming the file, line and field of the first thing it cannot read.
std::vector<AccuracyRow> readAccuracyCsv(const std::filesystem::path& file);

/// The Markdown tables: per set (means over the recordings with an error
/// figure, how many started) and per run; with `before`, each figure as
/// "before -> after" where it differs: a set over the recordings both runs
/// hold (each mean over those with the figure in both), a run where the
/// same set and recording is in `before`. Sets only `before` holds are named.
std::string accuracyMarkdown(const std::vector<AccuracyRow>& rows, const std::vector<AccuracyRow>* before,
                             const std::string& header);

}  // namespace rilo
