// Office sessions with the second system (IMU-Ultrasonic-UWB paper) written as recordings:
// TDoA and ultrasonic samples read back identically and replay through the
// replay source, and the files of a session without them are exactly those
// of before they existed (the committed golden-walk recording; imu, range
// and ground truth unchanged when TDoA or ultrasonic are switched on).
#include <gtest/gtest.h>

#include <atomic>
#include <bit>
#include <limits>
#include <string>
#include <variant>
#include <vector>

#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"
#include "hal/replay/replay_source.h"
#include "replay_test_util.h"
#include "sim/office_recording.h"
#include "sim/office_tdoa.h"
#include "sim/office_ultrasonic.h"
#include "support/source_tree.h"

namespace rilo::sim {
namespace {

using rilo::testing::fileText;
using rilo::testing::ScratchDir;

bool same(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

OfficeScenarioParams params(std::uint64_t seed, double duration_s) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  return p;
}

class CollectingSink final : public SampleSink {
 public:
  void push(const Sample& sample) noexcept override { samples.push_back(sample); }
  void fault(const SourceFault& f) noexcept override { faults.push_back(f); }
  std::vector<Sample> samples;
  std::vector<SourceFault> faults;
};

/// Lines of a text file.
std::vector<std::string> linesOf(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = text.find('\n', start);
    lines.push_back(text.substr(start, end == std::string::npos ? std::string::npos : end - start));
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return lines;
}

TEST(OfficeTdoaRecording, DefaultOutputIsTheCommittedGoldenWalk) {
  // tests/data/golden-walk was written by `rilo sim tests/data/golden-walk --seed 7
  // --seconds 24 --plan default --truth-hz 50` before TDoA and ultrasonic
  // existed: with both off, the simulator must still write exactly those
  // files. (If the default simulation is changed on purpose, this reference
  // goes with it.)
  const std::filesystem::path golden = rilo::testing::sourceDir() / "tests" / "data" / "golden-walk";
  ASSERT_TRUE(std::filesystem::exists(golden / recording::kImuFile)) << golden;
  ScratchDir dir;
  OfficeScenarioParams p = params(7, 0.4 * 60.0);
  ScenarioRecordingOptions o;
  o.name = "golden-walk";
  o.description =
      "rilo sim: default office plan, seed 7, 8 anchors, 0.4 min walk, ranging 40.0 Hz (4 per cycle), packet loss "
      "0.05, NLOS severity 1.00";
  o.truth_rate_hz = 50.0;
  writeOfficeRecording(p, dir.path(), o);
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kTagsFile, recording::kImuFile,
                             recording::kRangeFile, recording::kGroundTruthFile}) {
    const std::string want = fileText(golden / f), got = fileText(dir.path() / f);
    ASSERT_FALSE(want.empty()) << f;
    EXPECT_TRUE(want == got) << f << " differs from the committed golden-walk recording";
  }
  EXPECT_FALSE(std::filesystem::exists(dir.path() / recording::kTdoaFile));
  EXPECT_FALSE(std::filesystem::exists(dir.path() / recording::kUltrasonicFile));
}

TEST(OfficeTdoaRecording, TdoaAndUltrasonicLeaveTheOtherStreamsUnchanged) {
  ScratchDir plain, us, tdoa_twr, tdoa_only;
  OfficeScenarioParams p = params(9, 20.0);
  ScenarioRecordingOptions o;
  o.name = "same";
  const OfficeStats st_plain = writeOfficeRecording(p, plain.path(), o);
  OfficeScenarioParams pu = p;
  pu.ultrasonic.enabled = true;
  const OfficeStats st_us = writeOfficeRecording(pu, us.path(), o);
  OfficeScenarioParams pt = p;
  pt.tdoa.enabled = true;
  pt.tdoa.keep_twr = true;
  writeOfficeRecording(pt, tdoa_twr.path(), o);
  pt.tdoa.keep_twr = false;
  pt.ultrasonic.enabled = true;
  const OfficeStats st_tdoa = writeOfficeRecording(pt, tdoa_only.path(), o);

  for (std::string_view f : {recording::kImuFile, recording::kGroundTruthFile, recording::kTagsFile}) {
    const std::string want = fileText(plain.path() / f);
    ASSERT_FALSE(want.empty()) << f;
    EXPECT_TRUE(want == fileText(us.path() / f)) << f << " changed with ultrasonic";
    EXPECT_TRUE(want == fileText(tdoa_twr.path() / f)) << f << " changed with tdoa";
    EXPECT_TRUE(want == fileText(tdoa_only.path() / f)) << f << " changed with tdoa + ultrasonic";
  }
  const std::string ranges = fileText(plain.path() / recording::kRangeFile);
  ASSERT_FALSE(ranges.empty());
  EXPECT_TRUE(ranges == fileText(us.path() / recording::kRangeFile)) << "range.csv changed with ultrasonic";
  EXPECT_TRUE(ranges == fileText(tdoa_twr.path() / recording::kRangeFile)) << "range.csv changed with --keep-twr";
  EXPECT_FALSE(std::filesystem::exists(tdoa_only.path() / recording::kRangeFile));  // TDoA replaces SS-TWR
  EXPECT_EQ(st_us.ranges, st_plain.ranges);
  EXPECT_EQ(st_tdoa.ranges, 0u);
  EXPECT_GT(st_tdoa.tdoa.measurements, 0u);
  EXPECT_EQ(st_plain.tdoa.measurements, 0u);
  EXPECT_EQ(st_plain.ultrasonic.pings, 0u);

  // anchors.csv: the UWB anchors unchanged, then the beacons.
  const std::vector<std::string> a_plain = linesOf(fileText(plain.path() / recording::kAnchorsFile));
  const std::vector<std::string> a_us = linesOf(fileText(us.path() / recording::kAnchorsFile));
  ASSERT_EQ(a_us.size(), a_plain.size() + 4u);
  for (std::size_t i = 0; i < a_plain.size(); ++i) EXPECT_EQ(a_us[i], a_plain[i]);
  for (std::size_t i = a_plain.size(); i < a_us.size(); ++i) EXPECT_NE(a_us[i].find(",ultrasonic,"), std::string::npos);
  // meta.yaml: only the ultrasonic lever arm, resp. the ranging kind, differ.
  const std::vector<std::string> m_plain = linesOf(fileText(plain.path() / recording::kMetaFile));
  const std::vector<std::string> m_us = linesOf(fileText(us.path() / recording::kMetaFile));
  const std::vector<std::string> m_twr = linesOf(fileText(tdoa_twr.path() / recording::kMetaFile));
  ASSERT_EQ(m_us.size(), m_plain.size());
  ASSERT_EQ(m_twr.size(), m_plain.size());
  int us_diff = 0, twr_diff = 0;
  for (std::size_t i = 0; i < m_plain.size(); ++i) {
    if (m_us[i] != m_plain[i]) {
      ++us_diff;
      EXPECT_NE(m_us[i].find("lever_arm: [0, 0.03, 0.14]"), std::string::npos) << m_us[i];
    }
    if (m_twr[i] != m_plain[i]) {
      ++twr_diff;
      EXPECT_EQ(m_twr[i], "ranging: tdoa");
    }
  }
  EXPECT_EQ(us_diff, 1);
  EXPECT_EQ(twr_diff, 1);
}

TEST(OfficeTdoaRecording, ReadsBackIdenticallyAndReplays) {
  ScratchDir dir;
  OfficeScenarioParams p = params(10, 30.0);
  p.tdoa.enabled = true;
  p.tdoa.packet_reception = 0.4;
  p.ultrasonic.enabled = true;
  ScenarioRecordingOptions o;
  o.name = "tdoa-ultrasonic";
  const OfficeStats st = writeOfficeRecording(p, dir.path(), o);

  ReadReport report;
  const Recording rec = readRecording(dir.path(), &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(report.skipped_rows, 0u);
  EXPECT_EQ(rec.meta.ranging, RangingKind::kTdoa);
  EXPECT_EQ(rec.meta.ultrasonic_lever_arm_m, p.ultrasonic.p_b_receiver);
  EXPECT_EQ(rec.meta.uwb_lever_arm_m, p.p_b_tag);
  EXPECT_TRUE(rec.ranges.empty());

  // The anchors: the UWB ones, then the beacons with their own ids.
  const OfficeSetup setup = makeOfficeSetup(p);
  ASSERT_EQ(rec.anchors.size(), setup.p_w_anchors.size() + setup.p_w_ultrasonic.size());
  for (std::size_t i = 0; i < rec.anchors.size(); ++i) {
    const bool uwb = i < setup.p_w_anchors.size();
    EXPECT_EQ(rec.anchors[i].id, i);
    EXPECT_EQ(rec.anchors[i].kind, uwb ? AnchorKind::kUwb : AnchorKind::kUltrasonic);
    EXPECT_EQ(rec.anchors[i].p_w_anchor,
              uwb ? setup.p_w_anchors[i] : setup.p_w_ultrasonic[i - setup.p_w_anchors.size()]);
  }

  // Every TDoA and ultrasonic sample is in the files, bit for bit.
  OfficeTdoaStream tdoa(p, setup);
  TdoaSample ts;
  TdoaTruth tt;
  std::size_t n = 0;
  while (tdoa.next(ts, tt)) {
    ASSERT_LT(n, rec.tdoa.size());
    const TdoaSample& r = rec.tdoa[n++];
    ASSERT_EQ(r.t_ns, ts.t_ns);
    ASSERT_EQ(r.anchor_a, ts.anchor_a);
    ASSERT_EQ(r.anchor_b, ts.anchor_b);
    ASSERT_TRUE(same(r.diff_m, ts.diff_m));
    ASSERT_EQ(r.los, ts.los);
  }
  EXPECT_EQ(n, rec.tdoa.size());
  EXPECT_EQ(n, st.tdoa.measurements);
  EXPECT_GT(n, 500u);
  OfficeUltrasonicStream ultrasonic(p, setup);
  UltrasonicSample us;
  UltrasonicTruth ut;
  n = 0;
  while (ultrasonic.next(us, ut)) {
    ASSERT_LT(n, rec.ultrasonic.size());
    const UltrasonicSample& r = rec.ultrasonic[n++];
    ASSERT_EQ(r.t_ns, us.t_ns);
    ASSERT_EQ(r.anchor_id, us.anchor_id);
    ASSERT_TRUE(same(r.range_m, us.range_m));
    ASSERT_EQ(r.los, us.los);
  }
  EXPECT_EQ(n, rec.ultrasonic.size());
  EXPECT_EQ(n, st.ultrasonic.measurements);
  EXPECT_GT(n, 20u);

  // The replay source pushes all of them, merged in time order.
  ReplaySource src(dir.path());
  CollectingSink sink;
  std::atomic<bool> stop{false};
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  EXPECT_TRUE(sink.faults.empty());
  std::size_t imu = 0, ranges = 0, tdoa_n = 0, ultrasonic_n = 0;
  std::int64_t last_t = std::numeric_limits<std::int64_t>::min();
  for (const Sample& s : sink.samples) {
    const std::int64_t t = std::visit([](const auto& m) { return m.t_ns; }, s);
    ASSERT_GE(t, last_t);
    last_t = t;
    switch (s.index()) {
      case 0: ++imu; break;
      case 1: ++ranges; break;
      case 2: ++tdoa_n; break;
      case 3: ++ultrasonic_n; break;
      default: break;
    }
  }
  EXPECT_EQ(imu, rec.imu.size());
  EXPECT_EQ(ranges, 0u);
  EXPECT_EQ(tdoa_n, rec.tdoa.size());
  EXPECT_EQ(ultrasonic_n, rec.ultrasonic.size());
  // TDoA rows refer to UWB anchors, ultrasonic rows to beacons.
  for (const Sample& s : sink.samples) {
    if (const auto* t = std::get_if<TdoaSample>(&s)) {
      ASSERT_EQ(rec.findAnchor(t->anchor_a)->kind, AnchorKind::kUwb);
      ASSERT_EQ(rec.findAnchor(t->anchor_b)->kind, AnchorKind::kUwb);
    } else if (const auto* u = std::get_if<UltrasonicSample>(&s)) {
      ASSERT_EQ(rec.findAnchor(u->anchor_id)->kind, AnchorKind::kUltrasonic);
    }
  }
}

}  // namespace
}  // namespace rilo::sim
