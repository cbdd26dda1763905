// The accuracy table (evaluation/accuracy_table.h): its variants over the
// committed office demo, the first-path-free copy, the CSV it writes and reads
// back (and refuses when malformed), and the before/after Markdown.
#include "evaluation/accuracy_table.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval_test_support.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

ReportRecording demo() { return loadReportRecording(testing::officeDemoDir()); }

AccuracyRow row(const std::string& set, const std::string& recording, double online, double smoothed) {
  AccuracyRow r;
  r.set = set;
  r.recording = recording;
  r.started = std::isfinite(online);
  r.online_mean_m = online;
  r.online_max_m = std::isfinite(online) ? 3.0 * online : kNaN;
  r.smoothed_mean_m = smoothed;
  r.height_offset_m = std::isfinite(online) ? -0.13 : kNaN;
  if (r.started) {
    r.first_position_s = 0.5;
    r.first_full_state_s = 6.75;
  }
  r.tracked_share = r.started ? 0.98 : 0.0;
  r.update_mean_ms = 0.3;
  r.update_max_ms = 4.0;
  r.covariance_horizontal_in_95 = r.started ? 0.9 : kNaN;
  r.covariance_vertical_in_95 = r.started ? 0.97 : kNaN;
  return r;
}

std::string expectThrowMessage(const std::filesystem::path& file) {
  try {
    (void)readAccuracyCsv(file);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  ADD_FAILURE() << "readAccuracyCsv accepted " << file;
  return "";
}

TEST(AccuracyTable, WithoutFirstPathLeavesEverythingButTheColumn) {
  const Recording rec = demo().data;
  ASSERT_TRUE(hasFirstPath(rec));
  const Recording stripped = withoutFirstPath(rec);
  EXPECT_FALSE(hasFirstPath(stripped));
  ASSERT_EQ(stripped.ranges.size(), rec.ranges.size());
  for (std::size_t i = 0; i < rec.ranges.size(); ++i) {
    EXPECT_EQ(stripped.ranges[i].t_ns, rec.ranges[i].t_ns);
    EXPECT_EQ(stripped.ranges[i].range_m, rec.ranges[i].range_m);
    EXPECT_EQ(stripped.ranges[i].anchor_id, rec.ranges[i].anchor_id);
    EXPECT_TRUE(std::isnan(stripped.ranges[i].fp_power_dbm));
    EXPECT_EQ(std::isnan(stripped.ranges[i].rssi_dbm), std::isnan(rec.ranges[i].rssi_dbm));
  }
  EXPECT_EQ(stripped.imu.size(), rec.imu.size());
  EXPECT_EQ(stripped.groundtruth.size(), rec.groundtruth.size());
}

TEST(AccuracyTable, RunsEveryRateAsRecordedAndWithoutTheFirstPath) {
  ReportRecording with = demo();
  ReportRecording without = with;
  without.label = "demo-no-fp";
  without.data = withoutFirstPath(with.data);
  AccuracyOptions options;
  options.rates_hz = {40.0, 1.0};
  std::vector<std::size_t> progress;
  options.progress = [&](std::size_t done, std::size_t total) {
    EXPECT_EQ(total, 6u);
    progress.push_back(done);
  };
  const std::vector<AccuracyRow> rows =
      runAccuracyTable({{"demo", with}, {"other", without}}, ReplaySettings{}, options);
  EXPECT_EQ(progress, (std::vector<std::size_t>{0, 1, 2, 3, 4, 5, 6}));
  // The demo at two rates, as recorded and without the column; the copy
  // without a column only as recorded, in a group of its own after the first.
  ASSERT_EQ(rows.size(), 6u);
  const std::vector<std::string> sets = {"demo, all ranges", "demo, all ranges, first path removed", "demo, 1 Hz",
                                         "demo, 1 Hz, first path removed", "other, all ranges", "other, 1 Hz"};
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(rows[i].set, sets[i]);
    EXPECT_TRUE(rows[i].error.empty()) << rows[i].error;
  }
  EXPECT_EQ(rows[0].recording, "office-demo");
  EXPECT_EQ(rows[4].recording, "demo-no-fp");
  // At the full rate the demo tracks, decimetre-level, within seconds.
  for (const AccuracyRow* r : {&rows[0], &rows[1], &rows[4]}) {
    EXPECT_TRUE(r->started) << r->set;
    EXPECT_LT(r->online_mean_m, 0.5) << r->set;
    EXPECT_LT(r->smoothed_mean_m, r->online_max_m) << r->set;
    EXPECT_GT(r->tracked_share, 0.7) << r->set;
    ASSERT_TRUE(r->first_position_s.has_value()) << r->set;
    EXPECT_LT(*r->first_position_s, 5.0) << r->set;
    ASSERT_TRUE(r->first_full_state_s.has_value()) << r->set;
    EXPECT_GE(*r->first_full_state_s, *r->first_position_s) << r->set;
    EXPECT_GT(r->update_mean_ms, 0.0) << r->set;
    EXPECT_GE(r->update_max_ms, r->update_mean_ms) << r->set;
    EXPECT_LT(std::abs(r->height_offset_m), r->online_mean_m + 1e-12) << r->set;
    // Shares of the published poses inside their covariance's 95 % region.
    EXPECT_GT(r->covariance_horizontal_in_95, 0.0) << r->set;
    EXPECT_LE(r->covariance_horizontal_in_95, 1.0) << r->set;
    EXPECT_GT(r->covariance_vertical_in_95, 0.0) << r->set;
    EXPECT_LE(r->covariance_vertical_in_95, 1.0) << r->set;
  }
  // The copy is the demo without its column: the same run as the stripped
  // variant (a replay is deterministic, bit for bit, on any thread).
  EXPECT_EQ(rows[4].online_mean_m, rows[1].online_mean_m);
  EXPECT_EQ(rows[5].online_mean_m, rows[3].online_mean_m);
}

TEST(AccuracyTable, ARunThatThrowsIsARowNotAnAbort) {
  ReportRecording good = demo();
  ReportRecording broken = good;
  broken.label = "no-imu";
  broken.data.imu.clear();
  AccuracyOptions options;
  options.rates_hz = {40.0};
  options.without_first_path = false;
  const std::vector<AccuracyRow> rows = runAccuracyTable({{"g", good}, {"g", broken}}, ReplaySettings{}, options);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_TRUE(rows[0].error.empty());
  EXPECT_TRUE(rows[0].started);
  EXPECT_FALSE(rows[1].error.empty());
  EXPECT_FALSE(rows[1].started);
  EXPECT_TRUE(std::isnan(rows[1].online_mean_m));
}

TEST(AccuracyTable, OptionsAreChecked) {
  const ReportRecording rec = demo();
  AccuracyOptions options;
  options.rates_hz = {};
  EXPECT_THROW(runAccuracyTable({{"g", rec}}, ReplaySettings{}, options), std::invalid_argument);
  options.rates_hz = {-1.0};
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.rates_hz = {kNaN};
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.rates_hz = {1.0, 1.0};
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.rates_hz = {40.0, 80.0};  // both replay every range: one set twice
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.rates_hz = {40.0, 2.0, 1.0};
  EXPECT_NO_THROW(options.validate());
  options.jobs = 0;
  EXPECT_THROW(options.validate(), std::invalid_argument);
  options.jobs = 1;
  EXPECT_THROW(runAccuracyTable({}, ReplaySettings{}, options), std::invalid_argument);
}

TEST(AccuracyTable, CsvRoundTrip) {
  testing::TempDir dir("rilo-accuracy-csv");
  std::vector<AccuracyRow> rows = {row("own, all ranges", "office1", 0.2078, 0.1403),
                                   row("foreign, 1 Hz", "f15", kNaN, kNaN)};
  rows[1].first_position_s.reset();
  rows[1].update_mean_ms = rows[1].update_max_ms = kNaN;
  AccuracyRow failed = row("own, 1 Hz", "a \"quoted\", name", kNaN, kNaN);
  failed.error = "replay: no IMU samples, \"x\"\nsecond line";
  rows.push_back(failed);
  const std::filesystem::path file = dir / "accuracy.csv";
  writeAccuracyCsv(file, rows);
  const std::vector<AccuracyRow> back = readAccuracyCsv(file);
  ASSERT_EQ(back.size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_EQ(back[i].set, rows[i].set);
    EXPECT_EQ(back[i].recording, rows[i].recording);
    EXPECT_EQ(back[i].started, rows[i].started);
    std::string error = rows[i].error;  // one line in the file: a line break reads back as a space
    std::replace(error.begin(), error.end(), '\n', ' ');
    EXPECT_EQ(back[i].error, error);
    EXPECT_EQ(back[i].first_full_state_s.has_value(), rows[i].first_full_state_s.has_value());
    if (rows[i].first_full_state_s) {
      EXPECT_DOUBLE_EQ(*back[i].first_full_state_s, *rows[i].first_full_state_s);
    }
    EXPECT_EQ(back[i].first_position_s.has_value(), rows[i].first_position_s.has_value());
    if (rows[i].first_position_s) {
      EXPECT_DOUBLE_EQ(*back[i].first_position_s, *rows[i].first_position_s);
    }
    for (auto field : {&AccuracyRow::online_mean_m, &AccuracyRow::online_max_m, &AccuracyRow::smoothed_mean_m,
                       &AccuracyRow::height_offset_m, &AccuracyRow::update_mean_ms, &AccuracyRow::update_max_ms,
                       &AccuracyRow::covariance_horizontal_in_95, &AccuracyRow::covariance_vertical_in_95}) {
      if (std::isnan(rows[i].*field)) {
        EXPECT_TRUE(std::isnan(back[i].*field));
      } else {
        EXPECT_NEAR(back[i].*field, rows[i].*field, 1e-5 * std::abs(rows[i].*field));
      }
    }
    EXPECT_NEAR(back[i].tracked_share, rows[i].tracked_share, 1e-6);
  }
}

TEST(AccuracyTable, MalformedCsvNamesTheFileLineAndField) {
  testing::TempDir dir("rilo-accuracy-bad");
  const std::filesystem::path file = dir / "accuracy.csv";
  writeAccuracyCsv(file, {row("own, all ranges", "office1", 0.2, 0.1)});
  const std::string good = testing::readFile(file);
  const std::string header = good.substr(0, good.find('\n') + 1);
  const auto write = [&](const std::string& text) { std::ofstream(file, std::ios::trunc) << text; };

  write("set,recording\n");
  std::string msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(file.string() + ":1:"), std::string::npos) << msg;
  EXPECT_NE(msg.find("not an accuracy.csv"), std::string::npos) << msg;

  write("");
  EXPECT_NE(expectThrowMessage(file).find(":1:"), std::string::npos);

  write(header + "\"own, all ranges\",office1,1,0.2\n");
  msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(":2: 4 fields, expected 15"), std::string::npos) << msg;

  write(header + "\"own, all ranges\",office1,1,0.2x,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\n");
  msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(":2: field online_mean_m: not a number: '0.2x'"), std::string::npos) << msg;

  write(header + "\n\"own, all ranges\",office1,yes,0.2,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\n");
  msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(":3: field started"), std::string::npos) << msg;

  write(header + "\"own, all ranges,office1,1,0.2,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\n");
  msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(":2: unterminated quote"), std::string::npos) << msg;

  write(header + "\"own, all ranges\",office1,1,nan,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\n");
  msg = expectThrowMessage(file);
  EXPECT_NE(msg.find("field online_mean_m"), std::string::npos) << msg;

  // A file saved with CRLF line ends reads.
  write(header.substr(0, header.size() - 1) + "\r\n\"own, all ranges\",office1,1,0.2,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\r\n");
  EXPECT_EQ(readAccuracyCsv(file).size(), 1u);

  EXPECT_THROW(readAccuracyCsv(dir / "missing.csv"), std::runtime_error);
}

// A file written before session 44 has no covariance columns: it still reads
// (for --compare), the figures it lacks NaN; its own field count is asked for.
TEST(AccuracyTable, ReadsTheFilesWrittenBeforeTheCovarianceColumns) {
  testing::TempDir dir("rilo-accuracy-old");
  const std::filesystem::path file = dir / "accuracy.csv";
  const std::string old_header =
      "set,recording,started,online_mean_m,online_max_m,smoothed_mean_m,height_offset_m,first_position_s,"
      "first_full_state_s,tracked_share,update_mean_ms,update_max_ms,error\n";
  std::ofstream(file) << old_header << "\"own, all ranges\",office1,1,0.2,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,\n";
  const std::vector<AccuracyRow> back = readAccuracyCsv(file);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_DOUBLE_EQ(back[0].online_mean_m, 0.2);
  EXPECT_DOUBLE_EQ(back[0].update_max_ms, 4.0);
  EXPECT_TRUE(back[0].error.empty());
  EXPECT_TRUE(std::isnan(back[0].covariance_horizontal_in_95));
  EXPECT_TRUE(std::isnan(back[0].covariance_vertical_in_95));
  // Compared with it, the new figures show on their own.
  const std::string md = accuracyMarkdown({row("own, all ranges", "office1", 0.2, 0.1)}, &back, "# h");
  EXPECT_NE(md.find("-0.13 | 90 / 97 % |"), std::string::npos) << md;
  EXPECT_NE(md.find("| 98 % | 90 / 97 % |"), std::string::npos) << md;

  std::ofstream(file, std::ios::trunc) << old_header << "\"own, all ranges\",office1,1,0.2,0.6,0.1,-0.1,0.5,6.75,0.98,0.3,4,0.9,0.97,\n";
  const std::string msg = expectThrowMessage(file);
  EXPECT_NE(msg.find(":2: 15 fields, expected 13"), std::string::npos) << msg;
}

TEST(AccuracyTable, MarkdownShowsBeforeAndAfterOverTheRecordingsBothRunsHold) {
  const std::vector<AccuracyRow> before = {row("own, all ranges", "office1", 0.2000, 0.1400),
                                           row("own, all ranges", "office2", 0.3000, 0.2000),
                                           row("own, all ranges", "office3", 0.9000, 0.9000),
                                           row("foreign, all ranges", "f15", kNaN, kNaN)};
  const std::vector<AccuracyRow> after = {row("own, all ranges", "office1", 0.1800, 0.1400),
                                          row("own, all ranges", "office2", 0.3000, 0.2000),
                                          row("own, all ranges", "office9", 0.5000, 0.5000),
                                          row("foreign, all ranges", "f15", 0.5500, 0.4000)};
  const std::string md = accuracyMarkdown(after, &before, "# header");
  EXPECT_EQ(md.rfind("# header", 0), 0u);
  // The set over office1 and office2 (office3 and office9 are in one run only).
  EXPECT_NE(md.find("| own, all ranges | 3 | 2 | 2 | 0.2500 -> 0.2400 | 0.1700 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| foreign, all ranges | 1 | 1 | 0 -> 1 |"), std::string::npos) << md;
  // Per run: changed figures as before -> after, unchanged ones once, a new start.
  EXPECT_NE(md.find("| own, all ranges | office1 | 0.200 -> 0.180 | 0.140 | 0.60 -> 0.54 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| own, all ranges | office2 | 0.300 | 0.200 | 0.90 | -0.13 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| own, all ranges | office9 | 0.500 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| foreign, all ranges | f15 | never started -> 0.550 |"), std::string::npos) << md;
  // The covariance's share: once where unchanged, and per set over the recordings both runs hold.
  EXPECT_NE(md.find("| own, all ranges | office2 | 0.300 | 0.200 | 0.90 | -0.13 | 0.5 s / 6.8 s | 98 % | 90 / 97 % |"),
            std::string::npos)
      << md;
  EXPECT_NE(md.find("| 0.2500 -> 0.2400 | 0.1700 | -0.13 | 90 / 97 % |"), std::string::npos) << md;

  const std::string plain = accuracyMarkdown(after, nullptr, "# h");
  EXPECT_EQ(plain.find("->"), std::string::npos) << plain;
  EXPECT_NE(plain.find("| own, all ranges | 3 | 3 | 0.3267 | 0.2800 | -0.13 |"), std::string::npos) << plain;
}

TEST(AccuracyTable, ASetIsNotImprovedByARecordingThatStoppedStarting) {
  const std::vector<AccuracyRow> before = {row("own, 1 Hz", "a", 0.30, 0.20), row("own, 1 Hz", "b", 0.90, 0.60),
                                           row("gone | set", "c", 0.1, 0.1)};
  std::vector<AccuracyRow> after = {row("own, 1 Hz", "a", 0.30, 0.20), row("own, 1 Hz", "b", kNaN, kNaN)};
  after[1].error = "boom | twice\nover";
  const std::string md = accuracyMarkdown(after, &before, "# h");
  // The mean is over "a" alone on both sides: unchanged, while one start fewer shows.
  EXPECT_NE(md.find("| own, 1 Hz | 2 | 2 | 2 -> 1 | 0.3000 | 0.2000 | -0.13 |"), std::string::npos) << md;
  EXPECT_NE(md.find("Only in the earlier run: gone \\| set."), std::string::npos) << md;
  EXPECT_NE(md.find("| own, 1 Hz | b | failed: boom \\| twice over |"), std::string::npos) << md;
}

}  // namespace
}  // namespace rilo
