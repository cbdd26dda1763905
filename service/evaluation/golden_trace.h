#pragma once
// Golden-trace regression: a compact, deterministic text summary of one
// replayRecording() run (the run `rilo replay` does), committed next to a
// short recording so that any change of the estimator's behaviour shows up as
// a reviewable diff, and compared against a fresh run with per-field
// tolerances so that harmless floating-point drift does not fail the test.
//
// Format (version 1), one record per line, '#' starts a comment line:
//   golden_trace version=1
//   recording name=<meta.name> imu=<n> ranges=<n> groundtruth=<n>
//   settings smoother=.. noise=.. range_hz=.. lag_s=.. <optional>=<value|default> ...
//   counts initializations=.. reinitializations=.. ranges_used=.. updates=.. online=.. smoothed=..
//   ape_online   count=.. mean_m=.. median_m=.. rmse_m=.. max_m=.. horizontal_mean_m=.. vertical_mean_m=..
//   ape_smoothed (same fields; both ape lines only when the recording has ground truth)
//   state <t_s> | <smoothed x_m y_m z_m yaw_deg pitch_deg roll_deg> | <online, same six>
// State lines sit on a fixed time grid (multiples of period_ns covering the
// IMU span). Each pose is interpolated at the grid time between the two
// estimates around it (position linear, rotation geodesic); '-' replaces the
// six numbers when there is no estimate on both sides within max_gap_ns
// (before initialization, during a tracking loss). The online pose is
// interpolated between consecutive published estimates (the newest state
// after each update), the smoothed one between final smoothed states.
// Angles are ZYX Euler angles of R_w_b (yaw about world z, then pitch, roll).
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "evaluation/replay_run.h"
#include "hal/recording/recording.h"

namespace rilo {

struct GoldenTraceOptions {
  std::int64_t period_ns = 500'000'000;    ///< spacing of the state lines
  std::int64_t max_gap_ns = 1'000'000'000;  ///< widest gap between estimates still interpolated
};

/// Formats a finished run of `settings` over `rec`.
std::string formatGoldenTrace(const Recording& rec, const ReplaySettings& settings, const ReplayResult& run,
                              const GoldenTraceOptions& options = {});

/// Runs replayRecording(rec, settings) and formats it.
std::string goldenTrace(const Recording& rec, const ReplaySettings& settings = {},
                        const GoldenTraceOptions& options = {});

/// How far a fresh trace may be from the golden one before it is a difference.
struct GoldenTolerances {
  double position_m = 0.05;     ///< each of x, y, z of a state line
  double angle_deg = 1.0;       ///< each of yaw, pitch, roll (wrapped to +-180)
  double ape_m = 0.05;          ///< each *_m field of the ape lines
  std::uint64_t count_slack = 0;  ///< initializations, reinitializations, ranges_used
  double size_rel = 0.02;       ///< relative slack of updates, online, smoothed and ape counts
};

/// One parsed trace. Header records keep their fields as text (compared as
/// numbers or exactly, by field name); state lines are parsed to numbers.
struct GoldenTrace {
  struct Record {
    std::size_t line = 0;  ///< 1-based line in the source
    std::string kind;      ///< first word: golden_trace, recording, settings, counts, ape_online, ape_smoothed
    std::vector<std::pair<std::string, std::string>> fields;  ///< key=value in file order
  };
  struct State {
    std::size_t line = 0;
    std::int64_t t_ms = 0;  ///< grid time (ms), the key that matches lines of two traces
    std::string t_text;     ///< as written (s)
    std::optional<std::array<double, 6>> smoothed, online;  ///< x y z (m), yaw pitch roll (deg)
  };
  std::string source;  ///< file name (or label) used in messages
  std::vector<Record> records;
  std::vector<State> states;
};

/// Parses trace text. Throws std::runtime_error "<source>:<line>: <what>" on
/// a malformed line, an unknown record kind, a repeated record kind or state
/// times that do not strictly increase.
GoldenTrace parseGoldenTrace(std::string_view text, const std::string& source);

/// Differences of `actual` from `expected` beyond `tol`, one readable message
/// each ("<expected source>:<line> t=<t_s> s smoothed.x_m: expected .., actual .. (off by .., tolerance ..)");
/// missing and extra lines and fields are differences too. Empty: the traces agree.
std::vector<std::string> compareTraces(const GoldenTrace& expected, const GoldenTrace& actual,
                                       const GoldenTolerances& tol = {});

/// Parses both texts (see parseGoldenTrace; parse errors throw) and compares them.
std::vector<std::string> compareTraces(std::string_view expected_text, std::string_view actual_text,
                                       const GoldenTolerances& tol = {},
                                       const std::string& expected_source = "expected",
                                       const std::string& actual_source = "actual");

}  // namespace rilo
