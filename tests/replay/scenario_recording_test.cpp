// Simulated sessions written as recording folders read back identically; the
// streaming writer (rilo sim) writes the same files as the in-memory one.
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <system_error>

#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"
#include "replay_test_util.h"
#include "sim/office_recording.h"

namespace rilo::sim {
namespace {

using rilo::testing::fileText;
using rilo::testing::ScratchDir;

/// Same double bit for bit; any NaN equals any NaN.
bool same(double a, double b) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}
bool same(const Vec3& a, const Vec3& b) { return same(a.x(), b.x()) && same(a.y(), b.y()) && same(a.z(), b.z()); }

OfficeScenarioParams officeParams(std::uint64_t seed, double duration_s) {
  OfficeScenarioParams p;
  p.seed = seed;
  p.duration_s = duration_s;
  return p;
}

/// Every sample of `s` is in `rec`, unchanged.
void expectScenarioInRecording(const Scenario& s, const Recording& rec, const ScenarioRecordingOptions& o) {
  EXPECT_EQ(rec.meta.name, o.name);
  EXPECT_EQ(rec.meta.description, o.description);
  EXPECT_TRUE(same(rec.meta.gravity_m_s2, s.params.gravity_m_s2));
  EXPECT_EQ(rec.meta.imu_rate_hz, s.params.imu_rate_hz);
  EXPECT_EQ(rec.meta.gyro_noise_density, s.params.gyro_noise_density);
  EXPECT_EQ(rec.meta.accel_noise_density, s.params.accel_noise_density);
  EXPECT_EQ(rec.meta.gyro_bias_random_walk, s.params.gyro_bias_walk);
  EXPECT_EQ(rec.meta.accel_bias_random_walk, s.params.accel_bias_walk);
  EXPECT_TRUE(rec.meta.uwb_lever_arm_m && same(*rec.meta.uwb_lever_arm_m, s.p_b_tag));
  EXPECT_EQ(rec.meta.ranging, RangingKind::kSsTwr);

  ASSERT_EQ(rec.anchors.size(), s.p_w_anchors.size());
  for (std::size_t i = 0; i < rec.anchors.size(); ++i) {
    EXPECT_EQ(rec.anchors[i].id, i);
    EXPECT_TRUE(same(rec.anchors[i].p_w_anchor, s.p_w_anchors[i]));
    EXPECT_EQ(rec.anchors[i].kind, AnchorKind::kUwb);
    EXPECT_FALSE(rec.anchors[i].sigma_m.has_value());
  }
  ASSERT_EQ(rec.tags.size(), 1u);
  EXPECT_EQ(rec.tags[0].id, 0u);
  EXPECT_TRUE(same(rec.tags[0].p_b_tag, s.p_b_tag));

  ASSERT_EQ(rec.imu.size(), s.imu.size());
  for (std::size_t i = 0; i < s.imu.size(); ++i) {
    ASSERT_EQ(rec.imu[i].t_ns, s.imu[i].t_ns);
    ASSERT_TRUE(same(rec.imu[i].gyro_rad_s, s.imu[i].gyro_rad_s)) << "imu " << i;
    ASSERT_TRUE(same(rec.imu[i].accel_m_s2, s.imu[i].accel_m_s2)) << "imu " << i;
  }
  EXPECT_TRUE(rec.imu_temp_c.empty());
  ASSERT_EQ(rec.ranges.size(), s.ranges.size());
  for (std::size_t i = 0; i < s.ranges.size(); ++i) {
    const RangeSample &a = rec.ranges[i], &b = s.ranges[i];
    ASSERT_EQ(a.t_ns, b.t_ns);
    ASSERT_EQ(a.anchor_id, b.anchor_id);
    ASSERT_EQ(a.tag_id, b.tag_id);
    ASSERT_TRUE(same(a.range_m, b.range_m)) << "range " << i;
    ASSERT_TRUE(same(a.rssi_dbm, b.rssi_dbm)) << "range " << i;
    ASSERT_TRUE(same(a.fp_power_dbm, b.fp_power_dbm)) << "range " << i;
    ASSERT_EQ(a.los, b.los);
  }
  EXPECT_TRUE(rec.tdoa.empty());
  EXPECT_TRUE(rec.ultrasonic.empty());

  const std::vector<std::int64_t> t = groundTruthTimes(s.t0_ns, s.params.duration_s, o.truth_rate_hz);
  ASSERT_EQ(rec.groundtruth.size(), t.size());
  EXPECT_EQ(rec.groundtruth.front().t_ns, s.imu.front().t_ns);
  EXPECT_EQ(rec.groundtruth.back().t_ns, s.imu.back().t_ns);
  for (std::size_t i = 0; i < t.size(); ++i) {
    const GroundTruthPose& g = rec.groundtruth[i];
    const GroundTruthPose want = groundTruthAt(s, t[i]);
    ASSERT_EQ(g.t_ns, t[i]);
    ASSERT_TRUE(same(g.p_w_b, want.p_w_b));
    ASSERT_TRUE(same(g.q_w_b.w(), want.q_w_b.w()) && same(g.q_w_b.x(), want.q_w_b.x()) &&
                same(g.q_w_b.y(), want.q_w_b.y()) && same(g.q_w_b.z(), want.q_w_b.z()));
    ASSERT_TRUE(g.v_w_b.has_value());
    ASSERT_TRUE(same(*g.v_w_b, *want.v_w_b));
    // And it is the truth: pose and velocity of the trajectory.
    const KinematicState st = s.truthAt(t[i]);
    ASSERT_LT((g.pose().p - st.T_w_b.p).norm(), 1e-12);
    ASSERT_LT((g.pose().R - st.T_w_b.R).norm(), 1e-12);
  }
}

TEST(ScenarioRecording, OfficeSessionReadsBackIdentically) {
  ScratchDir dir;
  const Scenario s = simulateOfficeScenario(officeParams(11, 12.0));
  ScenarioRecordingOptions o;
  o.name = "office-11";
  o.description = "round trip";
  o.truth_rate_hz = 100.0;
  writeScenarioRecording(s, dir.path(), o);
  ReadReport report;
  const Recording rec = readRecording(dir.path(), &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(report.skipped_rows, 0u);
  expectScenarioInRecording(s, rec, o);
}

TEST(ScenarioRecording, SyntheticScenarioWithoutRssiReadsBackIdentically) {
  ScratchDir dir;
  ScenarioParams sp;
  sp.duration_s = 5.0;
  const Scenario s = simulateScenario(sp);  // rssi_dbm and fp_power_dbm are NaN there
  ScenarioRecordingOptions o;
  writeScenarioRecording(s, dir.path(), o);
  const Recording rec = readRecording(dir.path());
  expectScenarioInRecording(s, rec, o);
  EXPECT_TRUE(std::isnan(rec.ranges.front().rssi_dbm));
}

TEST(ScenarioRecording, StreamingWriterWritesTheSameFiles) {
  ScratchDir streamed, batch;
  const OfficeScenarioParams p = officeParams(12, 8.0);
  ScenarioRecordingOptions o;
  o.description = "same files";
  std::vector<double> progress;
  o.progress = [&](double f) { progress.push_back(f); };
  const OfficeStats st = writeOfficeRecording(p, streamed.path(), o);
  o.progress = nullptr;
  const OfficeSimulation sim = simulateOffice(p);
  writeScenarioRecording(sim.scenario, batch.path(), o);
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kTagsFile, recording::kImuFile,
                             recording::kRangeFile, recording::kGroundTruthFile}) {
    const std::string a = fileText(streamed / f), b = fileText(batch / f);
    EXPECT_FALSE(a.empty()) << f;
    EXPECT_TRUE(a == b) << f << " differs";
  }
  EXPECT_FALSE(std::filesystem::exists(streamed / recording::kTdoaFile));
  EXPECT_EQ(st.ranges, sim.stats.ranges);
  EXPECT_EQ(st.nlos, sim.stats.nlos);
  EXPECT_EQ(st.imu_samples, sim.scenario.imu.size());
  ASSERT_FALSE(progress.empty());
  EXPECT_TRUE(std::is_sorted(progress.begin(), progress.end()));
  EXPECT_EQ(progress.back(), 1.0);
}

TEST(ScenarioRecording, RefusesToOverwriteUnlessAsked) {
  ScratchDir dir;
  const OfficeScenarioParams p = officeParams(13, 2.0);
  writeOfficeRecording(p, dir.path());
  EXPECT_THROW(writeOfficeRecording(p, dir.path()), std::system_error);
  ScenarioRecordingOptions o;
  o.writer.overwrite = true;
  o.name = "again";
  EXPECT_NO_THROW(writeOfficeRecording(p, dir.path(), o));
  EXPECT_EQ(readRecording(dir.path()).meta.name, "again");
  o.truth_rate_hz = 0.0;
  EXPECT_THROW(writeOfficeRecording(p, dir.path(), o), std::invalid_argument);
}

}  // namespace
}  // namespace rilo::sim
