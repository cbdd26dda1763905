// Golden-trace regression test of the whole online pipeline.
//
// GoldenTraceRegression.GoldenWalkMatchesGoldenFile replays the short
// simulated recording tests/data/golden-walk (the run `rilo replay` does, with
// default settings), formats its trace (service/evaluation/golden_trace.h) and
// compares it with tests/data/golden-walk/golden_trace.txt within the default
// GoldenTolerances (positions 5 cm, angles 1 deg, APE 5 cm, run counts exact,
// update/state counts 2%). On a mismatch it lists every difference, writes the
// fresh trace to <build>/test-output/golden-walk/golden_trace.txt and prints
// the command that accepts it.
//
// Regenerating the golden file after an intended behaviour change:
//   RILO_UPDATE_GOLDEN=1 <build>/bin/rilo_test_evaluation --gtest_filter='GoldenTraceRegression.*'
// (or RILO_UPDATE_GOLDEN=1 ctest -R GoldenTraceRegression in the build dir).
// With RILO_UPDATE_GOLDEN=1 the test rewrites the golden file instead of
// comparing. Review the diff of golden_trace.txt and commit it with the
// change that caused it.
//
// The other tests check compareTraces and the trace format on hand-made runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "evaluation/golden_test_support.h"
#include "evaluation/golden_trace.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

namespace golden = rilo::testing::golden;

std::string joined(const std::vector<std::string>& lines, std::size_t max_lines = 60) {
  std::ostringstream out;
  for (std::size_t i = 0; i < lines.size() && i < max_lines; ++i) out << "  " << lines[i] << "\n";
  if (lines.size() > max_lines) out << "  ... and " << lines.size() - max_lines << " more\n";
  return out.str();
}

TEST(GoldenTraceRegression, GoldenWalkMatchesGoldenFile) {
  const std::filesystem::path recording_dir = golden::sourceDir() / "tests" / "data" / "golden-walk";
  const std::filesystem::path golden_file = recording_dir / "golden_trace.txt";
  const std::filesystem::path actual_file = golden::buildDir() / "test-output" / "golden-walk" / "golden_trace.txt";
  ASSERT_TRUE(std::filesystem::is_directory(recording_dir)) << "missing recording " << recording_dir;

  const Recording rec = readRecording(recording_dir);
  const auto start = std::chrono::steady_clock::now();
  const std::string actual = goldenTrace(rec);
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  RecordProperty("replay_s", std::to_string(run_s));

  // The same source tree must receive the file, so keep RILO_SOURCE_DIR if it is set.
  const char* source_env = std::getenv("RILO_SOURCE_DIR");
  const std::string accept_cmd =
      std::string(source_env != nullptr && source_env[0] != '\0' ? "RILO_SOURCE_DIR=" + golden::sourceDir().string() + " " : "") +
      "RILO_UPDATE_GOLDEN=1 " + golden::testBinary().string() + " --gtest_filter='GoldenTraceRegression.*'";
  if (golden::updateGoldenRequested()) {
    golden::writeFile(golden_file, actual);
    std::printf("RILO_UPDATE_GOLDEN=1: wrote %s (review its diff before committing)\n", golden_file.c_str());
    return;
  }

  bool found = false;
  const std::string expected = golden::readFile(golden_file, &found);
  if (!found) {
    golden::writeFile(actual_file, actual);
    FAIL() << "no golden trace " << golden_file << "; the current one is in " << actual_file
           << "\nto create the golden file run:\n  " << accept_cmd;
  }
  std::vector<std::string> diffs;
  try {
    diffs = compareTraces(expected, actual, GoldenTolerances{}, golden_file.string(), actual_file.string());
  } catch (const std::exception& e) {
    golden::writeFile(actual_file, actual);
    FAIL() << "cannot compare traces: " << e.what() << "\nthe current trace is in " << actual_file
           << "\nto accept it run:\n  " << accept_cmd;
  }
  if (!diffs.empty()) {
    golden::writeFile(actual_file, actual);
    ADD_FAILURE() << diffs.size() << " difference(s) from the golden trace beyond tolerance:\n"
                  << joined(diffs) << "the current trace is in " << actual_file
                  << "\ncompare: diff " << golden_file << " " << actual_file
                  << "\nif the change is intended, accept it with:\n  " << accept_cmd << "\n  (or: cp "
                  << actual_file << " " << golden_file << ")";
  } else {
    std::filesystem::remove(actual_file);  // no stale trace from an earlier failure
  }
}

// ---- the trace format and compareTraces on hand-made runs ----

constexpr std::int64_t kMs = 1'000'000;

/// A 3 s "recording" (IMU at 100 Hz, no ranges needed to format) and a run
/// with a state every 100 ms from 0.3 s on: position x = t, yaw = 10 deg * t.
struct HandMade {
  Recording rec;
  ReplayResult run;

  HandMade() {
    rec.meta.name = "hand made";
    for (std::int64_t t = 0; t <= 3000 * kMs; t += 10 * kMs) rec.imu.push_back(ImuSample{.t_ns = t});
    rec.ranges.resize(42);
    rec.groundtruth.resize(7);
    for (std::int64_t t = 300 * kMs; t <= 3000 * kMs; t += 100 * kMs) {
      run.smoothed.push_back({t, poseAt(t)});
      run.online.push_back({t, poseAt(t)});
    }
    run.ranges_used = 42;
    run.initializations = 1;
    run.updates.resize(100);
    PositionErrorStats ape;
    ape.ape_3d = {.mean = 0.1, .median = 0.09, .rmse = 0.12, .max = 0.3, .count = 28};
    run.ape_online = ape;
    run.ape_smoothed = ape;
  }
  static Pose3 poseAt(std::int64_t t_ns) {
    const double t = static_cast<double>(t_ns) * 1e-9;
    return Pose3(so3::exp(Vec3(0.0, 0.0, 10.0 * t * std::numbers::pi / 180.0)), Vec3(t, 2.0, 1.2));
  }
  std::string trace() const { return formatGoldenTrace(rec, ReplaySettings{}, run); }
};

/// The line of `text` that starts with `prefix` (empty if none).
std::string lineStartingWith(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind(prefix, 0) == 0) return line;
  }
  return {};
}

/// The state line of `text` at time `t_text` (as written, e.g. "1.500"), and its 1-based line number.
std::pair<std::string, std::size_t> stateLineAt(const std::string& text, const std::string& t_text) {
  std::istringstream in(text);
  std::size_t n = 0;
  for (std::string line; std::getline(in, line);) {
    ++n;
    std::istringstream words(line);
    std::string kind, t;
    words >> kind >> t;
    if (kind == "state" && t == t_text) return {line, n};
  }
  return {std::string(), 0};
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const std::size_t at = text.find(from);
  if (at == std::string::npos) throw std::invalid_argument("replaced: '" + from + "' not in text");
  return text.replace(at, from.size(), to);
}

bool anyContains(const std::vector<std::string>& lines, const std::vector<std::string>& parts) {
  return std::any_of(lines.begin(), lines.end(), [&](const std::string& l) {
    return std::all_of(parts.begin(), parts.end(), [&](const std::string& p) { return l.find(p) != std::string::npos; });
  });
}

TEST(GoldenTraceFormat, IsDeterministicAndCoversTheImuSpanOnAHalfSecondGrid) {
  const HandMade m;
  const std::string a = m.trace(), b = m.trace();
  EXPECT_EQ(a, b);
  const GoldenTrace t = parseGoldenTrace(a, "a");
  ASSERT_EQ(t.states.size(), 7u);  // 0.0, 0.5, ..., 3.0
  EXPECT_EQ(t.states.front().t_ms, 0);
  EXPECT_EQ(t.states.back().t_ms, 3000);
  EXPECT_FALSE(t.states[0].smoothed.has_value()) << "no estimate before the first state";
  EXPECT_FALSE(t.states[0].online.has_value());
  ASSERT_TRUE(t.states[2].smoothed.has_value());
  EXPECT_NEAR((*t.states[2].smoothed)[0], 1.0, 1e-9);   // x = t
  EXPECT_NEAR((*t.states[2].smoothed)[3], 10.0, 1e-9);  // yaw = 10 deg/s * t
  EXPECT_NEAR((*t.states[2].smoothed)[4], 0.0, 1e-9);
  EXPECT_NE(lineStartingWith(a, "counts ").find("initializations=1 reinitializations=0 ranges_used=42 updates=100"),
            std::string::npos)
      << a;
  EXPECT_NE(lineStartingWith(a, "recording ").find("name=hand_made imu=301 ranges=42 groundtruth=7"), std::string::npos)
      << a;
  EXPECT_NE(lineStartingWith(a, "ape_smoothed ").find("mean_m=0.1000"), std::string::npos) << a;
  EXPECT_NE(lineStartingWith(a, "settings ").find("smoother=d-isam2 noise=asymmetric"), std::string::npos) << a;
}

TEST(GoldenTraceFormat, InterpolatesBetweenStatesAndLeavesWideGapsEmpty) {
  HandMade m;
  // Only states at 0.4 s and 0.6 s around the 0.5 s grid time; then a 2 s gap.
  m.run.smoothed = {{400 * kMs, HandMade::poseAt(400 * kMs)},
                    {600 * kMs, HandMade::poseAt(600 * kMs)},
                    {2600 * kMs, HandMade::poseAt(2600 * kMs)}};
  const GoldenTrace t = parseGoldenTrace(m.trace(), "t");
  ASSERT_TRUE(t.states[1].smoothed.has_value());
  EXPECT_NEAR((*t.states[1].smoothed)[0], 0.5, 1e-9);
  EXPECT_NEAR((*t.states[1].smoothed)[3], 5.0, 1e-9);
  EXPECT_FALSE(t.states[2].smoothed.has_value()) << "1.0 s lies in a 2 s gap";
  EXPECT_FALSE(t.states[6].smoothed.has_value()) << "3.0 s is after the last state";
}

TEST(GoldenTraceCompare, IdenticalTracesAgree) {
  const std::string trace = HandMade().trace();
  EXPECT_TRUE(compareTraces(trace, trace).empty()) << joined(compareTraces(trace, trace));
}

TEST(GoldenTraceCompare, PositionBeyondToleranceIsReportedWithTimeAndField) {
  const HandMade m;
  HandMade moved;
  for (auto& p : moved.run.smoothed) {
    if (p.t_ns == 1500 * kMs) p.T_w_b.p.y() += 0.08;  // 8 cm > 5 cm
  }
  const std::vector<std::string> diffs = compareTraces(m.trace(), moved.trace(), GoldenTolerances{}, "golden.txt", "actual.txt");
  ASSERT_EQ(diffs.size(), 1u) << joined(diffs);
  EXPECT_NE(diffs[0].find("golden.txt:"), std::string::npos) << diffs[0];
  EXPECT_NE(diffs[0].find("t=1.500 s"), std::string::npos) << diffs[0];
  EXPECT_NE(diffs[0].find("smoothed.y_m"), std::string::npos) << diffs[0];
  EXPECT_NE(diffs[0].find("expected 2.000, actual 2.080"), std::string::npos) << diffs[0];
}

TEST(GoldenTraceCompare, SmallDriftWithinToleranceAgrees) {
  const HandMade m;
  HandMade drifted;
  for (auto& p : drifted.run.online) {
    p.T_w_b.p.z() += 0.03;
    p.T_w_b.R = p.T_w_b.R * so3::exp(Vec3(0.0, 0.01, 0.0));  // 0.57 deg
  }
  drifted.run.updates.resize(101);  // within 2 % of 100
  const std::vector<std::string> diffs = compareTraces(m.trace(), drifted.trace());
  EXPECT_TRUE(diffs.empty()) << joined(diffs);
}

TEST(GoldenTraceCompare, YawAcrossTheWrapAgrees) {
  const std::string expected = HandMade().trace();
  const std::string line = stateLineAt(expected, "1.000").first;
  ASSERT_FALSE(line.empty());
  // Replace the smoothed yaw (10.00) by 179.80 in one trace, -179.90 in the other.
  const std::string a = replaced(expected, line, replaced(line, "10.00", "179.80"));
  const std::string b = replaced(expected, line, replaced(line, "10.00", "-179.90"));
  EXPECT_TRUE(compareTraces(a, b).empty()) << joined(compareTraces(a, b));
}

TEST(GoldenTraceCompare, CountChangesAreReported) {
  const HandMade m;
  HandMade other;
  other.run.reinitializations = 1;
  other.run.updates.resize(110);
  const std::vector<std::string> diffs = compareTraces(m.trace(), other.trace());
  EXPECT_EQ(diffs.size(), 2u) << joined(diffs);
  EXPECT_TRUE(anyContains(diffs, {"counts.reinitializations", "expected 0, actual 1"})) << joined(diffs);
  EXPECT_TRUE(anyContains(diffs, {"counts.updates", "expected 100, actual 110"})) << joined(diffs);
}

TEST(GoldenTraceCompare, LostEstimateAndApeChangeAreReported) {
  const HandMade m;
  HandMade other;
  std::erase_if(other.run.online, [](const auto& p) { return p.t_ns >= 2000 * kMs; });
  other.run.ape_smoothed->ape_3d.rmse += 0.06;
  const std::vector<std::string> diffs = compareTraces(m.trace(), other.trace());
  EXPECT_TRUE(anyContains(diffs, {"t=2.500 s online", "expected an estimate"})) << joined(diffs);
  EXPECT_TRUE(anyContains(diffs, {"ape_smoothed.rmse_m", "expected 0.1200, actual 0.1800"})) << joined(diffs);
}

TEST(GoldenTraceCompare, MissingLinesAreReported) {
  const std::string expected = HandMade().trace();
  const std::string state_line = stateLineAt(expected, "2.000").first;
  const std::string ape_line = lineStartingWith(expected, "ape_online ");
  ASSERT_FALSE(state_line.empty());
  ASSERT_FALSE(ape_line.empty());
  const std::string actual = replaced(replaced(expected, state_line + "\n", ""), ape_line + "\n", "");
  const std::vector<std::string> diffs = compareTraces(expected, actual, GoldenTolerances{}, "golden.txt", "actual.txt");
  EXPECT_EQ(diffs.size(), 2u) << joined(diffs);
  EXPECT_TRUE(anyContains(diffs, {"golden.txt:", "t=2.000 s", "state line missing in actual.txt"})) << joined(diffs);
  EXPECT_TRUE(anyContains(diffs, {"golden.txt:", "ape_online", "line missing in actual.txt"})) << joined(diffs);
  // And the other way round: lines only the actual trace has.
  const std::vector<std::string> extra = compareTraces(actual, expected, GoldenTolerances{}, "golden.txt", "actual.txt");
  EXPECT_TRUE(anyContains(extra, {"actual.txt:", "t=2.000 s", "extra state line"})) << joined(extra);
  EXPECT_TRUE(anyContains(extra, {"actual.txt:", "ape_online", "extra line"})) << joined(extra);
}

TEST(GoldenTraceCompare, MalformedGoldenLineNamesFileAndLine) {
  const std::string good = HandMade().trace();
  const auto expectParseError = [&](const std::string& bad, const std::string& where, const std::string& what) {
    try {
      compareTraces(bad, good, GoldenTolerances{}, "golden_trace.txt", "actual");
      ADD_FAILURE() << "no error for a trace with " << what;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(where), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  // Line numbers: find the 1-based line of a given prefix in `good`.
  const auto lineOf = [&](const std::string& prefix) {
    std::istringstream in(good);
    std::size_t n = 0;
    for (std::string line; std::getline(in, line);) {
      ++n;
      if (line.rfind(prefix, 0) == 0) return n;
    }
    return std::size_t{0};
  };
  const auto [state, state_no] = stateLineAt(good, "1.500");
  ASSERT_FALSE(state.empty());
  expectParseError(replaced(good, state, replaced(state, "1.500", "1.5x0")), "golden_trace.txt:" + std::to_string(state_no) + ":",
                   "is not a number");
  expectParseError(replaced(good, state, state.substr(0, state.rfind(' '))), "golden_trace.txt:" + std::to_string(state_no) + ":",
                   "needs 6");
  const std::string counts = lineStartingWith(good, "counts ");
  expectParseError(replaced(good, counts, replaced(counts, "updates=100", "updates=lots")),
                   "golden_trace.txt:" + std::to_string(lineOf("counts ")) + ":", "is not a count");
  expectParseError(replaced(good, counts, counts + " stray"), "golden_trace.txt:" + std::to_string(lineOf("counts ")) + ":",
                   "not key=value");
  expectParseError(good + "bogus line\n", "golden_trace.txt:", "unknown line kind 'bogus'");
  expectParseError(good + state + "\n", "golden_trace.txt:", "does not follow");
}

}  // namespace
}  // namespace rilo
