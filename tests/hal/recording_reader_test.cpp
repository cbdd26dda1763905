// The reader's policy on malformed input: every case gives the documented
// error or warning, with the right file, line and column.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <string>

#include "hal/recording/csv_parser.h"
#include "hal/recording/number_text.h"
#include "hal/recording/recording_reader.h"
#include "recording_test_util.h"

namespace rilo {
namespace {

using recording::parseAnchors;
using recording::parseGroundTruth;
using recording::parseImu;
using recording::parseRanges;
using recording::parseTdoa;
using recording::parseUltrasonic;
using testing::expectRecordingError;
using testing::TempDir;
using testing::writeText;

constexpr const char* kImuHeader = "t_ns,wx,wy,wz,ax,ay,az\n";

struct ImuResult {
  std::vector<ImuSample> imu;
  std::vector<double> temp;
  ReadReport report;
};

ImuResult readImu(const std::string& text) {
  ImuResult r;
  parseImu(text, "imu.csv", r.imu, r.temp, r.report);
  return r;
}

RecordingError imuError(const std::string& text) {
  return expectRecordingError([&] { readImu(text); });
}

std::vector<Anchor> anchorsFixture() {
  return {Anchor{1, Vec3(0, 0, 2), AnchorKind::kUwb, std::nullopt},
          Anchor{2, Vec3(5, 0, 2), AnchorKind::kUwb, std::nullopt},
          Anchor{9, Vec3(0, 5, 3), AnchorKind::kUltrasonic, std::nullopt}};
}

TEST(RecordingReader, ParsesPlainImu) {
  const ImuResult r = readImu(std::string(kImuHeader) +
                              "1403636579758555392,0.1,-0.2,0.3,9.81,0,-1e-3\n"
                              "1403636579763555584,1,2,3,4,5,6\n");
  ASSERT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.imu[0].t_ns, 1403636579758555392);  // exact int64, no double on the way
  EXPECT_EQ(r.imu[1].t_ns, 1403636579763555584);
  EXPECT_EQ(r.imu[0].gyro_rad_s, Vec3(0.1, -0.2, 0.3));
  EXPECT_EQ(r.imu[0].accel_m_s2, Vec3(9.81, 0, -1e-3));
  EXPECT_TRUE(r.temp.empty());
  EXPECT_TRUE(r.report.warnings.empty());
}

TEST(RecordingReader, MissingRequiredColumnNamesFileLineColumn) {
  const RecordingError e = imuError("t_ns,wx,wy,wz,ay,az\n1,0,0,0,0,0\n");
  EXPECT_EQ(e.file(), "imu.csv");
  EXPECT_EQ(e.line(), 1u);
  EXPECT_EQ(e.column(), "ax");
  EXPECT_STREQ(e.what(), "imu.csv:1: column 'ax': required column missing from the header");
}

TEST(RecordingReader, BadNumberNamesFileLineColumn) {
  const RecordingError e = imuError(std::string(kImuHeader) + "1,0,0,0,0,0,0\n2,0,0,0,abc,0,0\n");
  EXPECT_STREQ(e.what(), "imu.csv:3: column 'ax': 'abc' is not a number");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.column(), "ax");
  // Partly numeric fields and locale-style decimals are not numbers either.
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,1.5x,0\n").column(), "ay");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,0,+1\n").column(), "az");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,0,\n").detail(), "empty field, expected a number");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,0,1e999\n").detail(), "'1e999' is out of range for a number");
}

TEST(RecordingReader, TimestampMustBeAnExactInt64) {
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1.5,0,0,0,0,0,0\n").detail(), "'1.5' is not an integer");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1e9,0,0,0,0,0,0\n").column(), "t_ns");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "9223372036854775808,0,0,0,0,0,0\n").detail(),
            "'9223372036854775808' is out of range for an integer");
  const ImuResult r = readImu(std::string(kImuHeader) + "-9223372036854775808,0,0,0,0,0,0\n9223372036854775807,0,0,0,0,0,0\n");
  ASSERT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.imu[1].t_ns, std::numeric_limits<std::int64_t>::max());
}

TEST(RecordingReader, NonFiniteValuesAreErrors) {
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "infinity"}) {
    const RecordingError e = imuError(std::string(kImuHeader) + "1,0," + bad + ",0,0,0,0\n");
    EXPECT_EQ(e.line(), 2u) << bad;
    EXPECT_EQ(e.column(), "wy") << bad;
    EXPECT_EQ(e.detail(), recording::quoteField(bad) + " is not finite");
  }
  // Optional columns too: blank means unknown, "nan" is not accepted.
  ReadReport rep;
  const RecordingError e = expectRecordingError([&] {
    parseRanges("t_ns,anchor_id,range_m,rssi_dbm\n1,1,2.0,nan\n", "range.csv", anchorsFixture(), {}, rep);
  });
  EXPECT_EQ(e.column(), "rssi_dbm");
  const auto ok = parseRanges("t_ns,anchor_id,range_m,rssi_dbm\n1,1,2.0,\n", "range.csv", anchorsFixture(), {}, rep);
  ASSERT_EQ(ok.size(), 1u);
  EXPECT_TRUE(std::isnan(ok[0].rssi_dbm));
  EXPECT_TRUE(std::isnan(ok[0].fp_power_dbm));
  EXPECT_EQ(ok[0].los, -1);
  EXPECT_EQ(ok[0].tag_id, 0u);
}

TEST(RecordingReader, WrongFieldCountIsAnError) {
  const RecordingError e = imuError(std::string(kImuHeader) + "1,0,0,0,0,0,0\n2,0,0,0,0,0\n3,0,0,0,0,0,0\n");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.column(), "");
  EXPECT_STREQ(e.what(), "imu.csv:3: expected 7 fields (as in the header), found 6");
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,0,0,0\n5,0,0,0,0,0,0\n").line(), 2u);
}

TEST(RecordingReader, OutOfOrderTimestampsAreErrors) {
  const RecordingError e = imuError(std::string(kImuHeader) + "10,0,0,0,0,0,0\n20,0,0,0,0,0,0\n15,0,0,0,0,0,0\n");
  EXPECT_EQ(e.line(), 4u);
  EXPECT_EQ(e.column(), "t_ns");
  EXPECT_EQ(e.detail(), "t_ns 15 is before t_ns 20 of line 3 (rows must be sorted by time)");

  ReadReport rep;
  const RecordingError r = expectRecordingError([&] {
    parseRanges("t_ns,anchor_id,range_m\n10,1,1\n10,2,1\n9,1,1\n", "range.csv", anchorsFixture(), {}, rep);
  });
  EXPECT_EQ(r.line(), 4u);
  EXPECT_EQ(r.column(), "t_ns");
  const RecordingError g = expectRecordingError([&] {
    parseGroundTruth("t_ns,px,py,pz,qw,qx,qy,qz\n5,0,0,0,1,0,0,0\n4,0,0,0,1,0,0,0\n", "groundtruth.csv", rep);
  });
  EXPECT_EQ(g.line(), 3u);
}

TEST(RecordingReader, ExactDuplicateImuRowIsSkippedWithAWarning) {
  const ImuResult r = readImu(std::string(kImuHeader) + "10,1,2,3,4,5,6\n10,1.0,2,3,4,5,6e0\n20,0,0,0,0,0,0\n");
  ASSERT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.report.skipped_rows, 1u);
  ASSERT_EQ(r.report.warnings.size(), 1u);
  EXPECT_EQ(r.report.warnings[0].file, "imu.csv");
  EXPECT_EQ(r.report.warnings[0].line, 3u);
  EXPECT_EQ(r.report.warnings[0].column, "t_ns");
  EXPECT_EQ(r.report.warnings[0].message, "imu.csv:3: column 't_ns': duplicate of line 2 skipped");

  // Same t_ns, different values: ambiguous, an error.
  const RecordingError e = imuError(std::string(kImuHeader) + "10,1,2,3,4,5,6\n10,1,2,3,4,5,7\n");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.detail(), "t_ns 10 repeats line 2 with different values");
}

TEST(RecordingReader, EventFilesShareTimestampsButNotIds) {
  ReadReport rep;
  const auto anchors = anchorsFixture();
  const auto ok = parseRanges("t_ns,anchor_id,range_m\n10,1,1.5\n10,2,2.5\n11,1,1.6\n", "range.csv", anchors, {}, rep);
  EXPECT_EQ(ok.size(), 3u);
  EXPECT_TRUE(rep.warnings.empty());

  const auto dup = parseRanges("t_ns,anchor_id,range_m\n10,1,1.5\n10,2,2.5\n10,1,1.5\n", "range.csv", anchors, {}, rep);
  EXPECT_EQ(dup.size(), 2u);
  ASSERT_EQ(rep.warnings.size(), 1u);
  EXPECT_EQ(rep.warnings[0].line, 4u);
  EXPECT_EQ(rep.warnings[0].message, "range.csv:4: column 't_ns': duplicate of line 2 skipped");
  EXPECT_EQ(rep.skipped_rows, 1u);

  const RecordingError e = expectRecordingError([&] {
    parseRanges("t_ns,anchor_id,range_m\n10,1,1.5\n10,2,2.5\n10,1,1.7\n", "range.csv", anchors, {}, rep);
  });
  EXPECT_EQ(e.line(), 4u);
  EXPECT_EQ(e.detail(), "t_ns 10 repeats line 2 (same t_ns and ids) with different values");

  const auto tdoa = parseTdoa("t_ns,anchor_a,anchor_b,diff_m\n1,1,2,0.5\n1,2,1,-0.5\n1,1,2,0.5\n", "tdoa.csv", anchors, rep);
  EXPECT_EQ(tdoa.size(), 2u);
  const auto us = parseUltrasonic("t_ns,anchor_id,range_m\n1,9,2\n1,9,2\n", "ultrasonic.csv", anchors, rep);
  EXPECT_EQ(us.size(), 1u);
}

TEST(RecordingReader, TdoaReceiveDiagnosticsAreOptionalAndChecked) {
  ReadReport rep;
  const auto anchors = anchorsFixture();
  const auto rows = parseTdoa(
      "t_ns,anchor_a,anchor_b,diff_m,rssi_a_dbm,fp_power_a_dbm,rssi_b_dbm,fp_power_b_dbm,los\n"
      "1,1,2,0.5,-80.5,-83,-90,-101.25,0\n"
      "2,2,1,-0.5,,,-85,-87,\n",
      "tdoa.csv", anchors, rep);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].rssi_a_dbm, -80.5);
  EXPECT_EQ(rows[0].fp_power_a_dbm, -83.0);
  EXPECT_EQ(rows[0].rssi_b_dbm, -90.0);
  EXPECT_EQ(rows[0].fp_power_b_dbm, -101.25);
  EXPECT_EQ(rows[0].los, 0);
  EXPECT_TRUE(std::isnan(rows[1].rssi_a_dbm));  // empty field: not reported
  EXPECT_TRUE(std::isnan(rows[1].fp_power_a_dbm));
  EXPECT_EQ(rows[1].fp_power_b_dbm, -87.0);
  EXPECT_EQ(rows[1].los, -1);
  // Without the columns (older recordings, UTIL imports) every value is NaN.
  const auto bare = parseTdoa("t_ns,anchor_a,anchor_b,diff_m\n1,1,2,0.5\n", "tdoa.csv", anchors, rep);
  ASSERT_EQ(bare.size(), 1u);
  EXPECT_TRUE(std::isnan(bare[0].rssi_b_dbm));

  RecordingError e = expectRecordingError([&] {
    parseTdoa("t_ns,anchor_a,anchor_b,diff_m,rssi_b_dbm\n1,1,2,0.5,-80\n2,1,2,0.5,loud\n", "tdoa.csv", anchors, rep);
  });
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.column(), "rssi_b_dbm");
  e = expectRecordingError([&] {
    parseTdoa("t_ns,anchor_a,anchor_b,diff_m,fp_power_a_dbm\n1,1,2,0.5,nan\n", "tdoa.csv", anchors, rep);
  });
  EXPECT_EQ(e.line(), 2u);
  EXPECT_EQ(e.column(), "fp_power_a_dbm");
  // Same time and pair with other diagnostics is a conflict, not a duplicate.
  e = expectRecordingError([&] {
    parseTdoa("t_ns,anchor_a,anchor_b,diff_m,rssi_a_dbm\n1,1,2,0.5,-80\n1,1,2,0.5,-81\n", "tdoa.csv", anchors, rep);
  });
  EXPECT_EQ(e.line(), 3u);
}

TEST(RecordingReader, UnknownOrWrongKindAnchorIsAnError) {
  ReadReport rep;
  const auto anchors = anchorsFixture();
  RecordingError e = expectRecordingError(
      [&] { parseRanges("t_ns,anchor_id,range_m\n1,1,2\n2,3,2\n", "range.csv", anchors, {}, rep); });
  EXPECT_STREQ(e.what(), "range.csv:3: column 'anchor_id': anchor 3 is not in anchors.csv");
  e = expectRecordingError([&] { parseRanges("t_ns,anchor_id,range_m\n1,9,2\n", "range.csv", anchors, {}, rep); });
  EXPECT_EQ(e.detail(), "anchor 9 is of kind 'ultrasonic', expected 'uwb'");
  e = expectRecordingError(
      [&] { parseTdoa("t_ns,anchor_a,anchor_b,diff_m\n1,1,7,0.5\n", "tdoa.csv", anchors, rep); });
  EXPECT_EQ(e.column(), "anchor_b");
  EXPECT_EQ(e.line(), 2u);
  e = expectRecordingError(
      [&] { parseTdoa("t_ns,anchor_a,anchor_b,diff_m\n1,2,2,0.5\n", "tdoa.csv", anchors, rep); });
  EXPECT_EQ(e.column(), "anchor_b");
  e = expectRecordingError(
      [&] { parseUltrasonic("t_ns,anchor_id,range_m\n1,1,2\n", "ultrasonic.csv", anchors, rep); });
  EXPECT_EQ(e.column(), "anchor_id");
  EXPECT_EQ(e.detail(), "anchor 1 is of kind 'uwb', expected 'ultrasonic'");
  e = expectRecordingError(
      [&] { parseRanges("t_ns,anchor_id,range_m\n1,-1,2\n", "range.csv", anchors, {}, rep); });
  EXPECT_EQ(e.detail(), "'-1' is not an unsigned 32-bit integer");
}

TEST(RecordingReader, UnknownTagIsAnError) {
  ReadReport rep;
  const auto anchors = anchorsFixture();
  RecordingError e = expectRecordingError(
      [&] { parseRanges("t_ns,anchor_id,range_m,tag_id\n1,1,2,1\n", "range.csv", anchors, {}, rep); });
  EXPECT_EQ(e.column(), "tag_id");
  EXPECT_EQ(e.detail(), "tag 1 is unknown (without tags.csv only tag 0 exists)");
  const std::vector<Tag> tags{Tag{4, Vec3::Zero()}, Tag{5, Vec3::Zero()}};
  e = expectRecordingError(
      [&] { parseRanges("t_ns,anchor_id,range_m,tag_id\n1,1,2,4\n1,1,2,0\n", "range.csv", anchors, tags, rep); });
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.detail(), "tag 0 is not in tags.csv");
  const auto ok = parseRanges("t_ns,anchor_id,range_m,tag_id\n1,1,2,4\n1,1,2,5\n", "range.csv", anchors, tags, rep);
  EXPECT_EQ(ok.size(), 2u);
}

TEST(RecordingReader, TruncatedLastLineIsSkippedWithAWarning) {
  // A crash cut the last line: too few fields.
  ImuResult r = readImu(std::string(kImuHeader) + "1,0,0,0,0,0,0\n2,0,0,0,0,0,0\n3,0.1,0.2");
  EXPECT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.report.skipped_rows, 1u);
  ASSERT_EQ(r.report.warnings.size(), 1u);
  EXPECT_EQ(r.report.warnings[0].line, 4u);
  EXPECT_EQ(r.report.warnings[0].message,
            "imu.csv:4: truncated last line (no newline) skipped: expected 7 fields (as in the header), found 3");
  // Cut inside a number.
  r = readImu(std::string(kImuHeader) + "1,0,0,0,0,0,0\n2,0,0,0,0,0,1e");
  EXPECT_EQ(r.imu.size(), 1u);
  ASSERT_EQ(r.report.warnings.size(), 1u);
  EXPECT_EQ(r.report.warnings[0].column, "az");
  // Cut inside the timestamp: it looks out of order.
  r = readImu(std::string(kImuHeader) + "1000,0,0,0,0,0,0\n10");
  EXPECT_EQ(r.imu.size(), 1u);
  EXPECT_EQ(r.report.skipped_rows, 1u);
  // The same line with its newline is an error, not a warning.
  EXPECT_EQ(imuError(std::string(kImuHeader) + "1,0,0,0,0,0,0\n3,0.1,0.2\n").line(), 3u);
  // A complete last line without newline is kept, with a warning.
  r = readImu(std::string(kImuHeader) + "1,0,0,0,0,0,0\n2,0,0,0,0,0,0.5");
  ASSERT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.imu[1].accel_m_s2.z(), 0.5);
  EXPECT_EQ(r.report.skipped_rows, 0u);
  ASSERT_EQ(r.report.warnings.size(), 1u);
  EXPECT_EQ(r.report.warnings[0].line, 3u);
}

TEST(RecordingReader, EmptyFilesAndHeaderOnly) {
  // Required file without header: error.
  const RecordingError e = imuError("");
  EXPECT_STREQ(e.what(), "imu.csv: empty file: no header line");
  EXPECT_EQ(e.line(), 0u);
  EXPECT_EQ(imuError("\n\n").detail(), "empty file: no header line");
  // Optional file without header: warning, treated as absent.
  ReadReport rep;
  const auto ranges = parseRanges("", "range.csv", anchorsFixture(), {}, rep);
  EXPECT_TRUE(ranges.empty());
  ASSERT_EQ(rep.warnings.size(), 1u);
  EXPECT_EQ(rep.warnings[0].message, "range.csv: empty file (no header line): treated as absent");
  // Header only: no rows, nothing to say.
  const ImuResult r = readImu(kImuHeader);
  EXPECT_TRUE(r.imu.empty());
  EXPECT_TRUE(r.report.warnings.empty());
  ImuResult r2 = readImu("t_ns,wx,wy,wz,ax,ay,az");  // header without newline, complete
  EXPECT_TRUE(r2.imu.empty());
  EXPECT_TRUE(r2.report.warnings.empty());
  // A header cut short by a crash: the file counts as empty.
  rep = {};
  EXPECT_TRUE(parseRanges("t_ns,anch", "range.csv", anchorsFixture(), {}, rep).empty());
  EXPECT_EQ(rep.warnings.size(), 2u);  // truncated header + empty file
  EXPECT_EQ(imuError("t_ns,wx,w").detail(), "empty file: no header line");
}

TEST(RecordingReader, CrlfLineEndingsParseLikeLf) {
  const std::string lf = std::string(kImuHeader) + "1,0.5,0,0,0,0,9.81\n2,0.25,0,0,0,0,9.8\n";
  std::string crlf;
  for (char c : lf) {
    if (c == '\n') crlf += '\r';
    crlf += c;
  }
  const ImuResult a = readImu(lf);
  const ImuResult b = readImu(crlf);
  ASSERT_EQ(b.imu.size(), 2u);
  EXPECT_TRUE(b.report.warnings.empty());
  for (std::size_t i = 0; i < 2; ++i) {
    EXPECT_EQ(a.imu[i].t_ns, b.imu[i].t_ns);
    EXPECT_EQ(a.imu[i].gyro_rad_s, b.imu[i].gyro_rad_s);
    EXPECT_EQ(a.imu[i].accel_m_s2, b.imu[i].accel_m_s2);
  }
}

TEST(RecordingReader, UnknownColumnsAreIgnoredWithAWarning) {
  const ImuResult r = readImu("az,t_ns,frame_id,wx,wy,wz,ax,ay,temp_c,extra\n9.81,1,imu0,0.1,0.2,0.3,1,2,36.5,whatever\n");
  ASSERT_EQ(r.imu.size(), 1u);
  EXPECT_EQ(r.imu[0].t_ns, 1);
  EXPECT_EQ(r.imu[0].accel_m_s2, Vec3(1, 2, 9.81));  // picked by name, not position
  ASSERT_EQ(r.temp.size(), 1u);
  EXPECT_EQ(r.temp[0], 36.5);
  ASSERT_EQ(r.report.warnings.size(), 2u);
  EXPECT_EQ(r.report.warnings[0].message, "imu.csv:1: column 'frame_id': unknown column ignored");
  EXPECT_EQ(r.report.warnings[1].column, "extra");
  // A repeated column name is an error.
  const RecordingError e = imuError("t_ns,wx,wy,wz,ax,ay,az,wx\n");
  EXPECT_EQ(e.column(), "wx");
  EXPECT_EQ(e.line(), 1u);
}

TEST(RecordingReader, HashHeaderAndCommentLines) {
  const ImuResult r = readImu(
      "# t_ns,wx,wy,wz,ax,ay,az\n"
      "# exported by the simulator, seed 3\n"
      "1,0,0,0,0,0,0\n"
      "   # indented comment\n"
      "2,0,0,0,0,0,0\n");
  EXPECT_EQ(r.imu.size(), 2u);
  EXPECT_TRUE(r.report.warnings.empty());
  // Line numbers keep counting comment lines.
  const RecordingError e = imuError("#t_ns,wx,wy,wz,ax,ay,az\n#c\n#c\n1,0,0,0,0,0,x\n");
  EXPECT_EQ(e.line(), 4u);
}

TEST(RecordingReader, WhitespaceBlankLinesAndByteOrderMark) {
  const ImuResult r = readImu("\xEF\xBB\xBFt_ns, wx ,wy,wz,ax,ay,az\n1, 0.5 ,0,0,0,0,\t0\n\n2,0,0,0,0,0,0\n");
  ASSERT_EQ(r.imu.size(), 2u);
  EXPECT_EQ(r.imu[0].gyro_rad_s.x(), 0.5);
  ASSERT_EQ(r.report.warnings.size(), 2u);
  EXPECT_EQ(r.report.warnings[0].message, "imu.csv:1: UTF-8 byte order mark ignored");
  EXPECT_EQ(r.report.warnings[1].message, "imu.csv:3: blank line skipped");
}

TEST(RecordingReader, AnchorsAndTagsValidation) {
  ReadReport rep;
  const auto anchors = parseAnchors("id,x,y,z,kind,sigma\n1,0,0,2,,\n2,1,0,2,uwb,0.05\n3,1,1,3,ultrasonic,\n",
                                    "anchors.csv", rep);
  ASSERT_EQ(anchors.size(), 3u);
  EXPECT_EQ(anchors[0].kind, AnchorKind::kUwb);
  EXPECT_FALSE(anchors[0].sigma_m.has_value());
  EXPECT_EQ(anchors[1].sigma_m, 0.05);
  EXPECT_EQ(anchors[2].kind, AnchorKind::kUltrasonic);

  RecordingError e = expectRecordingError([&] { parseAnchors("id,x,y,z\n1,0,0,0\n1,1,1,1\n", "anchors.csv", rep); });
  EXPECT_STREQ(e.what(), "anchors.csv:3: column 'id': anchor id 1 already defined on line 2");
  e = expectRecordingError([&] { parseAnchors("id,x,y,z,kind\n1,0,0,0,lidar\n", "anchors.csv", rep); });
  EXPECT_EQ(e.column(), "kind");
  e = expectRecordingError([&] { parseAnchors("id,x,y,z,sigma\n1,0,0,0,-0.1\n", "anchors.csv", rep); });
  EXPECT_EQ(e.column(), "sigma");
  e = expectRecordingError([&] { parseAnchors("", "anchors.csv", rep); });
  EXPECT_EQ(e.detail(), "empty file: no header line");
  e = expectRecordingError([&] { recording::parseTags("id,x,y,z\n0,0,0,0\n0,0,0,1\n", "tags.csv", rep); });
  EXPECT_EQ(e.line(), 3u);
}

TEST(RecordingReader, LosAndGroundTruthValidation) {
  ReadReport rep;
  RecordingError e = expectRecordingError(
      [&] { parseRanges("t_ns,anchor_id,range_m,los\n1,1,2,1\n2,1,2,2\n", "range.csv", anchorsFixture(), {}, rep); });
  EXPECT_STREQ(e.what(), "range.csv:3: column 'los': '2' is not a valid los (0, 1 or empty)");

  e = expectRecordingError(
      [&] { parseGroundTruth("t_ns,px,py,pz,qw,qx,qy,qz\n1,0,0,0,0,0,0,0\n", "groundtruth.csv", rep); });
  EXPECT_EQ(e.column(), "qw");
  EXPECT_EQ(e.line(), 2u);
  e = expectRecordingError(
      [&] { parseGroundTruth("t_ns,px,py,pz,qw,qx,qy,qz,vx,vy\n", "groundtruth.csv", rep); });
  EXPECT_EQ(e.column(), "vz");
  EXPECT_EQ(e.line(), 1u);
  e = expectRecordingError([&] {
    parseGroundTruth("t_ns,px,py,pz,qw,qx,qy,qz,vx,vy,vz\n1,0,0,0,1,0,0,0,1,,3\n", "groundtruth.csv", rep);
  });
  EXPECT_EQ(e.column(), "vy");
  const auto gt =
      parseGroundTruth("t_ns,px,py,pz,qw,qx,qy,qz,vx,vy,vz\n1,0,0,0,1,0,0,0,,,\n2,1,2,3,0,1,0,0,4,5,6\n",
                       "groundtruth.csv", rep);
  ASSERT_EQ(gt.size(), 2u);
  EXPECT_FALSE(gt[0].v_w_b.has_value());
  EXPECT_EQ(*gt[1].v_w_b, Vec3(4, 5, 6));
  EXPECT_EQ(gt[1].q_w_b.x(), 1.0);  // w first in the file
  EXPECT_EQ(gt[1].q_w_b.w(), 0.0);
}

TEST(RecordingReader, FolderLevelErrorsNameTheFile) {
  TempDir dir;
  RecordingError e = expectRecordingError([&] { readRecording(dir / "missing"); });
  EXPECT_EQ(e.detail(), "not a recording folder");
  writeText(dir / "imu.csv", kImuHeader);
  e = expectRecordingError([&] { readRecording(dir.path()); });
  EXPECT_EQ(e.file(), (dir / "anchors.csv").string());
  EXPECT_EQ(e.detail(), "required file missing");
  writeText(dir / "anchors.csv", "id,x,y,z\n1,0,0,2\n");
  writeText(dir / "range.csv", "t_ns,anchor_id,range_m\n1,1,2\n2,5,2\n");
  e = expectRecordingError([&] { readRecording(dir.path()); });
  EXPECT_EQ(e.file(), (dir / "range.csv").string());
  EXPECT_EQ(std::string(e.what()), (dir / "range.csv").string() + ":3: column 'anchor_id': anchor 5 is not in anchors.csv");
  writeText(dir / "range.csv", "t_ns,anchor_id,range_m\n1,1,2\n");
  writeText(dir / "groundtruth.csv", "");
  ReadReport rep;
  const Recording r = readRecording(dir.path(), &rep);
  EXPECT_EQ(r.ranges.size(), 1u);
  ASSERT_EQ(rep.warnings.size(), 1u);
  EXPECT_EQ(rep.warnings[0].file, (dir / "groundtruth.csv").string());
  std::filesystem::create_directory(dir / "tdoa.csv");
  e = expectRecordingError([&] { readRecording(dir.path()); });
  EXPECT_EQ(e.detail(), "not a regular file");
}

TEST(NumberText, ParsesAndFormatsExactly) {
  using recording::NumberStatus;
  double d = 0;
  EXPECT_EQ(recording::parseDouble("0.1", d), NumberStatus::kOk);
  EXPECT_EQ(d, 0.1);
  EXPECT_EQ(recording::parseDouble("", d), NumberStatus::kEmpty);
  EXPECT_EQ(recording::parseDouble("1,5", d), NumberStatus::kNotANumber);
  EXPECT_EQ(recording::parseDouble("0x10", d), NumberStatus::kNotANumber);
  EXPECT_EQ(recording::parseDouble("-inf", d), NumberStatus::kNonFinite);
  EXPECT_EQ(recording::parseDouble("1e-400", d), NumberStatus::kOutOfRange);
  std::uint32_t u = 0;
  EXPECT_EQ(recording::parseUint32("4294967296", u), NumberStatus::kOutOfRange);
  EXPECT_EQ(recording::parseUint32("4294967295", u), NumberStatus::kOk);
  std::string s;
  recording::appendDouble(s, 0.1 + 0.2);
  EXPECT_EQ(s, "0.30000000000000004");
  s.clear();
  recording::appendDouble(s, -0.0);
  EXPECT_EQ(s, "-0");
  std::mt19937_64 rng(5);
  for (int i = 0; i < 10000; ++i) {
    const double x = std::bit_cast<double>(rng());
    if (!std::isfinite(x)) continue;
    s.clear();
    recording::appendDouble(s, x);
    double y = 0;
    ASSERT_EQ(recording::parseDouble(s, y), NumberStatus::kOk) << s;
    EXPECT_EQ(std::bit_cast<std::uint64_t>(x), std::bit_cast<std::uint64_t>(y)) << s;
  }
}

}  // namespace
}  // namespace rilo
