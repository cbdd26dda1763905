// replayRecording on second-system recordings (IMU-Ultrasonic-UWB paper): range.csv is
// optional, --measurements chooses the kinds fed to the pipeline, --reception
// drops UWB packets (a TDoA epoch's rows together, a range alone) from a seed,
// and the per-kind counts say what was recorded, used and dropped.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <set>
#include <string>

#include "eval_test_support.h"
#include "evaluation/replay_run.h"
#include "hal/recording/recording_reader.h"
#include "sim/office_recording.h"

namespace rilo {
namespace {

TEST(MeasurementKinds, ParsesAnySubsetAndRefusesUnknownOrEmpty) {
  EXPECT_EQ(measurementKindsFromString("range,tdoa,ultrasonic"), (MeasurementKinds{true, true, true}));
  EXPECT_EQ(measurementKindsFromString("ultrasonic,tdoa"), (MeasurementKinds{false, true, true}));
  EXPECT_EQ(measurementKindsFromString("range"), (MeasurementKinds{true, false, false}));
  EXPECT_EQ(toString(MeasurementKinds{false, true, true}), "tdoa,ultrasonic");
  EXPECT_EQ(toString(MeasurementKinds{}), "range,tdoa,ultrasonic");
  EXPECT_THROW(measurementKindsFromString("range,twr"), std::invalid_argument);
  EXPECT_THROW(measurementKindsFromString(""), std::invalid_argument);
  try {
    measurementKindsFromString("lidar");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("lidar"), std::string::npos);
  }
}

/// A 30 s hall session with TDoA, the SS-TWR ranges kept, and ultrasonic beacons.
const Recording& hallRecording() {
  static const Recording rec = [] {
    testing::TempDir dir("replay-measurements");
    sim::OfficeScenarioParams p;
    p.seed = 3;
    p.duration_s = 30.0;
    p.plan = sim::OfficePlanKind::kHall;
    p.tdoa.enabled = true;
    p.tdoa.keep_twr = true;
    p.ultrasonic.enabled = true;
    sim::writeOfficeRecording(p, dir / "hall");
    return readRecording((dir / "hall").string());
  }();
  return rec;
}

TEST(ReplayMeasurements, EveryKindTheRecordingHasIsUsedByDefault) {
  const Recording& rec = hallRecording();
  ASSERT_FALSE(rec.ranges.empty());
  ASSERT_FALSE(rec.tdoa.empty());
  ASSERT_FALSE(rec.ultrasonic.empty());
  const ReplayResult run = replayRecording(rec, ReplaySettings());
  const MeasurementCounts& m = run.measurements;
  EXPECT_EQ(m.range.recorded, rec.ranges.size());
  EXPECT_EQ(m.range.used, rec.ranges.size());
  EXPECT_EQ(run.ranges_used, rec.ranges.size());
  EXPECT_EQ(m.tdoa.used, rec.tdoa.size());
  EXPECT_EQ(m.ultrasonic.used, rec.ultrasonic.size());
  EXPECT_EQ(m.range.dropped + m.tdoa.dropped + m.ultrasonic.dropped, 0u);
  EXPECT_TRUE(m.range.selected && m.tdoa.selected && m.ultrasonic.selected);
  EXPECT_GE(run.initializations, 1u);
  ASSERT_TRUE(run.ape_online.has_value());
  EXPECT_LT(run.ape_smoothed->ape_3d.rmse, 0.5);
}

// rilod refuses relinearization.recent_updates 0 with d-isam2 in its config;
// a replay's --smoother choice over a service configuration must too.
TEST(ReplayMeasurements, DiSam2OverAConfigWithoutRecentRelinearizationIsRefused) {
  const Recording& rec = hallRecording();
  ReplaySettings s;
  s.service_params = LocalizerParams();
  s.service_params->smoother.method = SmootherParams::Method::kGaussNewton;
  s.service_params->smoother.always_relinearize_recent_updates = 0;
  s.smoother = "isam2";
  EXPECT_EQ(localizerParamsFor(rec, s).smoother.always_relinearize_recent_updates, 0);
  s.smoother = "d-isam2";
  EXPECT_THROW(localizerParamsFor(rec, s), std::invalid_argument);
  s.service_params->smoother.always_relinearize_recent_updates = 1;
  EXPECT_EQ(localizerParamsFor(rec, s).smoother.method, SmootherParams::Method::kDamped);
}

TEST(ReplayMeasurements, OnlyTheSelectedKindsReachThePipeline) {
  const Recording& rec = hallRecording();
  ReplaySettings s;
  s.measurements = measurementKindsFromString("range");
  const ReplayResult ranges_only = replayRecording(rec, s);
  EXPECT_EQ(ranges_only.measurements.range.used, rec.ranges.size());
  EXPECT_EQ(ranges_only.measurements.tdoa.used, 0u);
  EXPECT_EQ(ranges_only.measurements.ultrasonic.used, 0u);
  EXPECT_FALSE(ranges_only.measurements.tdoa.selected);
  EXPECT_EQ(ranges_only.measurements.tdoa.recorded, rec.tdoa.size());
  // With TDoA rows the Localizer groups them into 25 ms states (with_tdoa):
  // the same data in the graph's 5 ms states make more updates.
  const ReplayResult all = replayRecording(rec, ReplaySettings());
  EXPECT_EQ(localizerParamsFor(rec, s).graph.same_state_window_ns, 5'000'000);
  EXPECT_EQ(localizerParamsFor(rec, ReplaySettings()).with_tdoa.state_window_ns, 25'000'000);
  ReplaySettings five_ms;
  five_ms.same_state_window_ms = 5.0;
  EXPECT_GT(replayRecording(rec, five_ms).updates.size(), all.updates.size() * 3 / 2);
  // Dynamic covariance by default when TDoA is used: the graph stream (the
  // Localizer's with_tdoa) and the EKF alike.
  EXPECT_TRUE(localizerParamsFor(rec, ReplaySettings()).with_tdoa.dynamic_covariance);
  EXPECT_TRUE(all.dynamic_covariance);
  ReplaySettings ekf_run;
  ekf_run.smoother = "ekf";
  EXPECT_TRUE(replayRecording(rec, ekf_run).dynamic_covariance);
  ekf_run.measurements = s.measurements;  // ranges only
  EXPECT_FALSE(replayRecording(rec, ekf_run).dynamic_covariance);
  EXPECT_FALSE(ranges_only.dynamic_covariance);
  ReplaySettings off;
  off.dynamic_covariance = false;
  EXPECT_FALSE(localizerParamsFor(rec, off).stream.dynamic_covariance.enabled);
  EXPECT_FALSE(localizerParamsFor(rec, off).with_tdoa.dynamic_covariance);
  EXPECT_FALSE(localizerParamsFor(rec, off).ekf.dynamic_covariance.enabled);
  EXPECT_FALSE(replayRecording(rec, off).dynamic_covariance);
  // The vertical speed prior by default, stiffer when TDoA is used (every
  // estimator; the EKF reads it from graph).
  EXPECT_EQ(localizerParamsFor(rec, ReplaySettings()).vertical_speed_sigma_m_s, kTdoaVerticalSpeedSigmaMs);
  EXPECT_EQ(localizerParamsFor(rec, s).vertical_speed_sigma_m_s, kTwoWayVerticalSpeedSigmaMs);
  ReplaySettings no_prior;
  no_prior.vertical_speed_sigma_m_s = 0.0;
  EXPECT_EQ(localizerParamsFor(rec, no_prior).vertical_speed_sigma_m_s, 0.0);
  ReplaySettings ekf;
  ekf.smoother = "ekf";
  const Localizer with_ekf(uwbAnchorsById(rec.anchors), localizerParamsFor(rec, ekf));
  EXPECT_EQ(with_ekf.params().graph.vertical_speed_sigma_m_s, kTdoaVerticalSpeedSigmaMs);
  // The standstill prior: LocalizerParams' default unless given; the tracker's graph gets it, the initializer's not.
  EXPECT_EQ(localizerParamsFor(rec, ReplaySettings()).zero_velocity_sigma_m_s, LocalizerParams().zero_velocity_sigma_m_s);
  EXPECT_GT(with_ekf.params().graph.zero_velocity_sigma_m_s, 0.0);
  EXPECT_EQ(with_ekf.params().init.graph.zero_velocity_sigma_m_s, 0.0);
  ReplaySettings no_standstill;
  no_standstill.zero_velocity_sigma_m_s = 0.0;
  EXPECT_EQ(localizerParamsFor(rec, no_standstill).zero_velocity_sigma_m_s, 0.0);
  EXPECT_EQ(replayRecording(rec, no_standstill).standstill_priors, 0u);
  EXPECT_GT(replayRecording(rec, ReplaySettings()).standstill_priors, 0u) << "the sim's wearer stops";
  // The ultrasonic beacons and the receiver's lever arm come from the recording.
  const LocalizerParams lp = localizerParamsFor(rec, ReplaySettings());
  EXPECT_EQ(lp.graph.p_b_ultrasonic, rec.meta.ultrasonic_lever_arm_m);
  for (const Anchor& a : rec.anchors) {
    if (a.kind != AnchorKind::kUltrasonic) continue;
    ASSERT_LT(a.id, lp.graph.p_w_ultrasonic.size());
    EXPECT_EQ(lp.graph.p_w_ultrasonic[a.id], a.p_w_anchor);
  }
}

TEST(ReplayMeasurements, RangeCsvIsOptionalButSomeSelectedKindIsNeeded) {
  Recording rec = hallRecording();
  rec.ranges.clear();
  ReplaySettings s;
  const ReplayResult tdoa_only = replayRecording(rec, s);  // TDoA and ultrasonic: initialized from them
  EXPECT_GE(tdoa_only.initializations, 1u) << tdoa_only.init_status;
  EXPECT_EQ(tdoa_only.measurements.range.recorded, 0u);
  ASSERT_TRUE(tdoa_only.ape_smoothed.has_value());
  EXPECT_LT(tdoa_only.ape_smoothed->ape_3d.rmse, 0.6);
  s.measurements = measurementKindsFromString("range");
  try {
    replayRecording(rec, s);
    FAIL() << "no range to replay";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("range"), std::string::npos) << e.what();
  }
  Recording no_imu = hallRecording();
  no_imu.imu.clear();
  EXPECT_THROW(replayRecording(no_imu, ReplaySettings()), std::runtime_error);
  ReplaySettings bad;
  bad.reception = 1.5;
  EXPECT_THROW(replayRecording(hallRecording(), bad), std::invalid_argument);
}

TEST(ReplayMeasurements, TdoaRowsFlaggedByTheirDiagnosticsAreCountedAndChangeTheEstimate) {
  Recording rec = hallRecording();
  rec.ranges.clear();
  ReplaySettings s;
  s.measurements = measurementKindsFromString("tdoa,ultrasonic");
  const ReplayResult on = replayRecording(rec, s);
  const MeasurementCount& t = on.measurements.tdoa;
  EXPECT_GT(t.flagged_one, 0u);
  EXPECT_GT(t.flagged_both, 0u);
  EXPECT_LT(t.flagged_one + t.flagged_both, t.used);  // the hall has LOS rows
  // Truly LOS rows are rarely flagged: the flags follow the truth.
  std::size_t los_rows = 0;
  for (const TdoaSample& row : rec.tdoa) los_rows += row.los == 1 ? 1 : 0;
  EXPECT_GE(t.used - t.flagged_one - t.flagged_both, los_rows * 9 / 10);

  s.tdoa_nlos_indicator = false;
  const ReplayResult off = replayRecording(rec, s);
  EXPECT_EQ(off.measurements.tdoa.flagged_one + off.measurements.tdoa.flagged_both, 0u);
  ASSERT_FALSE(on.online.empty());
  ASSERT_FALSE(off.online.empty());
  EXPECT_FALSE(on.online.back().T_w_b.p.isApprox(off.online.back().T_w_b.p, 1e-9));

  // Rows without diagnostics (UTIL imports, older recordings) are never flagged.
  for (TdoaSample& row : rec.tdoa) row.fp_power_b_dbm = row.fp_power_a_dbm = std::numeric_limits<double>::quiet_NaN();
  s.tdoa_nlos_indicator.reset();
  const ReplayResult bare = replayRecording(rec, s);
  EXPECT_EQ(bare.measurements.tdoa.flagged_one + bare.measurements.tdoa.flagged_both, 0u);
}

TEST(ReplayMeasurements, TdoaRowsDeepInNlosAreGatedCountedAndKeptFromTheEstimate) {
  Recording rec = hallRecording();
  rec.ranges.clear();
  auto deeperThan = [&](double gate_db) {
    std::size_t n = 0, los = 0;
    for (const TdoaSample& row : rec.tdoa) {
      if (std::max(row.rssi_a_dbm - row.fp_power_a_dbm, row.rssi_b_dbm - row.fp_power_b_dbm) > gate_db) {
        ++n;
        los += row.los == 1 ? 1 : 0;
      }
    }
    return std::pair{n, los};
  };
  ReplaySettings s;
  s.measurements = measurementKindsFromString("tdoa,ultrasonic");
  const ReplayResult by_default = replayRecording(rec, s);
  EXPECT_EQ(by_default.measurements.tdoa.deep_nlos, deeperThan(RangeImuGraphParams().tdoa_max_power_gap_db).first);
  EXPECT_EQ(by_default.measurements.tdoa.used, rec.tdoa.size());  // fed to the Localizer, which drops the deep ones

  s.tdoa_max_power_gap_db = 9.0;
  const ReplayResult strict = replayRecording(rec, s);
  const auto [deep, deep_los] = deeperThan(9.0);
  ASSERT_GT(deep, 20u);
  EXPECT_EQ(strict.measurements.tdoa.deep_nlos, deep);
  EXPECT_LE(deep_los * 10, deep);  // the gate follows the truth: few of them are line of sight

  s.tdoa_max_power_gap_db = std::numeric_limits<double>::infinity();
  const ReplayResult open = replayRecording(rec, s);
  EXPECT_EQ(open.measurements.tdoa.deep_nlos, 0u);
  ASSERT_FALSE(open.online.empty());
  ASSERT_FALSE(strict.online.empty());
  EXPECT_FALSE(open.online.back().T_w_b.p.isApprox(strict.online.back().T_w_b.p, 1e-9));

  // With the indicator off the diagnostics are not used at all.
  s.tdoa_max_power_gap_db = 9.0;
  s.tdoa_nlos_indicator = false;
  EXPECT_EQ(replayRecording(rec, s).measurements.tdoa.deep_nlos, 0u);
  s.tdoa_nlos_indicator.reset();

  // Without diagnostics nothing is gated, whatever the gate.
  for (TdoaSample& row : rec.tdoa) row.fp_power_b_dbm = row.fp_power_a_dbm = std::numeric_limits<double>::quiet_NaN();
  s.tdoa_max_power_gap_db = 9.0;
  EXPECT_EQ(replayRecording(rec, s).measurements.tdoa.deep_nlos, 0u);
}

TEST(ReplayMeasurements, TdoaPacketExcessLearntFromTheGapsLowersTheErrorAndNeedsDiagnostics) {
  Recording rec = hallRecording();
  rec.ranges.clear();
  ReplaySettings s;
  s.measurements = measurementKindsFromString("tdoa,ultrasonic");
  s.smoother = "sliding-window";
  s.lag_s = 10.0;
  const ReplayResult learnt = replayRecording(rec, s);
  s.tdoa_gap_excess = false;
  const ReplayResult plain = replayRecording(rec, s);
  ASSERT_TRUE(learnt.ape_smoothed && plain.ape_smoothed && learnt.ape_online && plain.ape_online);
  std::printf("hall 30 s, sliding window, 3D RMSE online / smoothed: %.3f / %.3f m learnt, %.3f / %.3f m without\n",
              learnt.ape_online->ape_3d.rmse, learnt.ape_smoothed->ape_3d.rmse, plain.ape_online->ape_3d.rmse,
              plain.ape_smoothed->ape_3d.rmse);
  EXPECT_LT(learnt.ape_smoothed->ape_3d.rmse, plain.ape_smoothed->ape_3d.rmse);
  EXPECT_LT(learnt.ape_online->ape_3d.rmse, plain.ape_online->ape_3d.rmse);

  // Rows without diagnostics teach nothing and are not corrected: the same run.
  for (TdoaSample& row : rec.tdoa) row.fp_power_b_dbm = row.fp_power_a_dbm = std::numeric_limits<double>::quiet_NaN();
  const ReplayResult bare_plain = replayRecording(rec, s);
  s.tdoa_gap_excess.reset();
  const ReplayResult bare_learnt = replayRecording(rec, s);
  ASSERT_EQ(bare_learnt.online.size(), bare_plain.online.size());
  ASSERT_FALSE(bare_plain.online.empty());
  EXPECT_TRUE(bare_learnt.online.back().T_w_b.p.isApprox(bare_plain.online.back().T_w_b.p, 1e-12));
}

TEST(ReplayMeasurements, ReceptionDropsWholeTdoaEpochsAndSingleRangesFromItsSeed) {
  Recording rec = hallRecording();
  // Give every other TDoA epoch a second row at the same time (a tag that
  // differences one packet against two references): they must go together.
  std::vector<TdoaSample> doubled;
  for (std::size_t k = 0; k < rec.tdoa.size(); ++k) {
    doubled.push_back(rec.tdoa[k]);
    if (k % 2 == 0) {
      TdoaSample twin = rec.tdoa[k];
      twin.anchor_a = (twin.anchor_b + 3) % 8;
      if (twin.anchor_a == twin.anchor_b || twin.anchor_a == rec.tdoa[k].anchor_a) continue;
      twin.diff_m += 0.5;
      doubled.push_back(twin);
    }
  }
  rec.tdoa = doubled;
  std::set<std::int64_t> epochs;
  for (const TdoaSample& d : rec.tdoa) epochs.insert(d.t_ns);

  ReplaySettings s;
  s.reception = 0.4;
  s.reception_seed = 9;
  s.smoother = "ekf";  // the cheapest estimator: this test is about the feed
  const ReplayResult a = replayRecording(rec, s);
  const MeasurementCounts& m = a.measurements;
  EXPECT_EQ(m.tdoa.used + m.tdoa.dropped, rec.tdoa.size());
  EXPECT_EQ(m.range.used + m.range.dropped, rec.ranges.size());
  EXPECT_EQ(m.ultrasonic.dropped, 0u);  // not a UWB packet
  EXPECT_EQ(m.ultrasonic.used, rec.ultrasonic.size());
  const double range_kept = static_cast<double>(m.range.used) / static_cast<double>(rec.ranges.size());
  EXPECT_NEAR(range_kept, 0.4, 0.05);
  const double rows_kept = static_cast<double>(m.tdoa.used) / static_cast<double>(rec.tdoa.size());
  EXPECT_NEAR(rows_kept, 0.4, 0.05);

  // Same seed: the same run; another seed: other packets.
  const ReplayResult again = replayRecording(rec, s);
  EXPECT_EQ(again.measurements.tdoa.used, m.tdoa.used);
  EXPECT_EQ(again.measurements.range.used, m.range.used);
  ASSERT_EQ(again.online.size(), a.online.size());
  for (std::size_t k = 0; k < a.online.size(); ++k) ASSERT_EQ(again.online[k].T_w_b.p, a.online[k].T_w_b.p);
  s.reception_seed = 10;
  const ReplayResult other = replayRecording(rec, s);
  EXPECT_NE(other.measurements.tdoa.used, m.tdoa.used);

  // Dropped rows go by epoch: the kept rows of a doubled epoch are both or none.
  // (The feed is internal; check the draw rule on the counts of a run where
  // only doubled epochs exist.)
  Recording pairs_only = rec;
  std::vector<TdoaSample> only_doubled;
  for (std::size_t k = 0; k + 1 < rec.tdoa.size(); ++k) {
    if (rec.tdoa[k].t_ns == rec.tdoa[k + 1].t_ns) {
      only_doubled.push_back(rec.tdoa[k]);
      only_doubled.push_back(rec.tdoa[k + 1]);
      ++k;
    }
  }
  ASSERT_GT(only_doubled.size(), 1000u);
  pairs_only.tdoa = only_doubled;
  s.reception_seed = 9;
  const ReplayResult p = replayRecording(pairs_only, s);
  EXPECT_EQ(p.measurements.tdoa.used % 2, 0u);
  EXPECT_EQ(p.measurements.tdoa.dropped % 2, 0u);

  // Reception 0: no UWB at all, the ultrasonic ranges alone.
  s.reception = 0.0;
  const ReplayResult none = replayRecording(rec, s);
  EXPECT_EQ(none.measurements.tdoa.used, 0u);
  EXPECT_EQ(none.measurements.range.used, 0u);
  EXPECT_EQ(none.measurements.ultrasonic.used, rec.ultrasonic.size());
}

TEST(ReplayMeasurements, ReceptionOneAndAllKindsOfATwrRecordingChangeNothing) {
  // The committed demo (range.csv only): the TDoA settings' defaults change
  // nothing for two-way ranges (golden_trace_test pins the whole run).
  const Recording rec = readRecording(testing::officeDemoDir().string());
  ASSERT_TRUE(rec.tdoa.empty());
  const LocalizerParams lp = localizerParamsFor(rec, ReplaySettings());
  EXPECT_EQ(lp.graph.same_state_window_ns, 5'000'000);
  EXPECT_FALSE(lp.stream.dynamic_covariance.enabled);
  EXPECT_FALSE(lp.ekf.dynamic_covariance.enabled);
  EXPECT_EQ(lp.vertical_speed_sigma_m_s, kTwoWayVerticalSpeedSigmaMs);
  ReplaySettings dc;
  dc.dynamic_covariance = true;
  EXPECT_TRUE(localizerParamsFor(rec, dc).stream.dynamic_covariance.enabled);
  EXPECT_TRUE(localizerParamsFor(rec, dc).ekf.dynamic_covariance.enabled);
  ReplaySettings window;
  window.same_state_window_ms = 12.5;
  EXPECT_EQ(localizerParamsFor(rec, window).graph.same_state_window_ns, 12'500'000);
}

}  // namespace
}  // namespace rilo
