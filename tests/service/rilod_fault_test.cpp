// rilod under injected faults, end to end: the real daemon replays a
// recording through its fault injection (sources.replay.faults) as fast as
// possible and publishes over real Cyclone DDS on loopback; this process
// subscribes like a ROS 2 node and checks that the service keeps publishing
// and that its status topic and log say what happened and why.
//
// Each test is one rilod run of 45-60 s of data: 2-8 s of wall time on a
// loaded 2-core machine (the smoother is the bottleneck, the replay waits for
// it: no sample is lost to the pace).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "hal/recording/recording_reader.h"
#include "rilod_runner.h"
#include "service_test_support.h"
#include "sim/office_recording.h"

namespace rilo {
namespace {

using namespace std::chrono_literals;
using testing::RilodOutput;

/// rilod's configuration for `recording` with `faults` (YAML list items,
/// 6-space indented), a fast status period and small queues (in a fast replay
/// the publisher runs at most a queue ahead of the estimator).
std::string config(const std::filesystem::path& recording, const std::string& faults) {
  const std::string rec = recording.string();
  return "sources:\n  mode: replay\n  replay:\n    path: " + rec +
         "\n    pace: as_fast_as_possible\n    shift_to_now: false\n    faults:\n" + faults +
         "anchors:\n  file: " + rec + "/anchors.csv\n" +
         "estimator:\n  smoother: d-isam2\n  range:\n    lever_arm_m: [0.06, 0.0, 0.10]\n" +
         "dds:\n  domain: " + std::to_string(testing::testDomain()) + "\n  loopback_only: true\n  stamp_clock: monotonic\n" +
         "realtime:\n  lock_memory: false\n  queue_capacity: 1024\n" +
         "status:\n  period_s: 0.05\n  imu_timeout_s: 0.1\n  range_timeout_s: 2.0\n";
}

std::filesystem::path officeDemo() { return testing::sourceDir() / "tests" / "data" / "office-demo"; }

std::string reasonOf(const dds::StatusMessage& m) { return std::string(m.status.reason.data()); }

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

/// The first status whose state is `state` and whose reason contains `part`, or null.
const dds::StatusMessage* findStatus(const RilodOutput& out, const std::string& state, const std::string& part) {
  for (const auto& s : out.status) {
    if (s.state_name == state && contains(reasonOf(s), part)) return &s;
  }
  return nullptr;
}

/// The status with the most published odometry (the last one the service sent).
const dds::StatusMessage& lastStatus(const RilodOutput& out) {
  return *std::max_element(out.status.begin(), out.status.end(), [](const auto& a, const auto& b) {
    return a.status.t_ns < b.status.t_ns;
  });
}

/// Tracking, or degraded only because the machine was slow (a late smoother
/// update: a loaded CI machine, a sanitizer build) — nothing the data did.
bool trackingApartFromLoad(const dds::StatusMessage& m) {
  if (m.state_name == "tracking") return true;
  if (m.state_name != "degraded") return false;
  std::string reason = reasonOf(m);
  std::size_t begin = 0;
  while (begin < reason.size()) {
    const std::size_t end = std::min(reason.find("; ", begin), reason.size());
    if (!contains(reason.substr(begin, end - begin), "late smoother update")) return false;
    begin = end + 2;
  }
  return true;
}

std::string statusTrail(const RilodOutput& out) {
  std::string trail;
  std::string previous;
  for (const auto& s : out.status) {
    const std::string line = s.state_name + ": " + reasonOf(s);
    if (line != previous) trail += "  " + line + "\n";
    previous = line;
  }
  return trail;
}

void expectOdometryClean(const RilodOutput& out) {
  ASSERT_FALSE(out.odometry.empty());
  for (std::size_t i = 0; i < out.odometry.size(); ++i) {
    const auto& o = out.odometry[i];
    ASSERT_TRUE(o.p_w_b.allFinite() && o.q_w_b.coeffs().allFinite() && o.v_b.allFinite()) << "odometry " << i;
    if (i > 0) {
      ASSERT_GT(o.stamp_ns, out.odometry[i - 1].stamp_ns) << "odometry " << i;
    }
  }
}

TEST(RilodFaults, RangingBlackoutDegradesWhileOdometryContinuesThenRecovers) {
  testing::TempDir dir("rilod-blackout");
  // 60 s of the default office walk (rilo sim --seed 1 --seconds 60): longer
  // than the committed demo, so that tracking has 15 s after the blackout.
  sim::OfficeScenarioParams params;
  params.seed = 1;
  params.duration_s = 60.0;
  const auto rec = dir / "rec";
  sim::writeOfficeRecording(params, rec);
  const Recording recording = readRecording(rec);
  const std::int64_t t0 = recording.imu.front().t_ns;
  const std::int64_t blackout_begin = t0 + 15'000'000'000, blackout_end = t0 + 45'000'000'000;

  const RilodOutput out = testing::runRilod(dir, config(rec, "      - {kind: range_blackout, at_s: 15, duration_s: 30}\n"),
                                            0.0, 60s);
  std::printf("rilod blackout run: %.1f s wall, %zu odometry, %zu poses, %zu status received\n", out.wall_s,
              out.odometry.size(), out.poses.size(), out.status.size());
  ASSERT_EQ(out.exit_code, 0) << out.log;
  ASSERT_FALSE(out.status.empty());

  // Degraded, saying why, from 2 s into the blackout (range_timeout_s).
  const dds::StatusMessage* degraded = findStatus(out, "degraded", "no ranging for");
  ASSERT_NE(degraded, nullptr) << "status trail:\n" << statusTrail(out);
  EXPECT_EQ(degraded->status.ranging_gaps, 1u);
  // Back to tracking, with nothing left to report.
  const dds::StatusMessage& last = lastStatus(out);
  EXPECT_TRUE(trackingApartFromLoad(last)) << "status trail:\n" << statusTrail(out);
  EXPECT_EQ(last.status.ranging_gaps, 1u);
  EXPECT_EQ(last.status.reinitializations, 0u) << "the estimator bridged the blackout on the IMU\n" << out.log;
  // Odometry kept going through the blackout: the service counted it ...
  // (43 s of 800 Hz IMU from 2 s into the blackout to the end, 34400 at
  // most; as fast as possible, the publisher skips the samples the estimator
  // has already passed, more of them on a loaded machine: 15836 with two
  // busy cores, so the bound asks for 10 s worth, not a share.)
  EXPECT_GT(last.status.published_odometry - degraded->status.published_odometry, 10u * 800u)
      << "odometry published from 2 s into the blackout to the end";
  // ... and it arrived (best effort: a share of it), with clean stamps.
  expectOdometryClean(out);
  const auto in_blackout = std::count_if(out.odometry.begin(), out.odometry.end(), [&](const auto& o) {
    return o.stamp_ns >= blackout_begin + 2'000'000'000 && o.stamp_ns < blackout_end;
  });
  EXPECT_GT(in_blackout, 100) << "odometry received from inside the blackout";
  // Recovered for real: the smoothed poses of the last 10 s are back near the truth.
  double sum = 0.0;
  int n = 0;
  for (const auto& p : out.poses) {
    if (p.stamp_ns < blackout_end + 5'000'000'000) continue;
    auto it = std::lower_bound(recording.groundtruth.begin(), recording.groundtruth.end(), p.stamp_ns,
                               [](const GroundTruthPose& g, std::int64_t t) { return g.t_ns < t; });
    if (it == recording.groundtruth.end()) continue;
    sum += (it->p_w_b - p.p_w_b).head<2>().norm();
    ++n;
  }
  ASSERT_GT(n, 100);
  std::printf("mean horizontal error over the last %d smoothed poses: %.3f m\n", n, sum / n);
  EXPECT_LT(sum / n, 1.0) << "mean horizontal error over the last " << n << " poses";
  // The log says it too.
  EXPECT_TRUE(contains(out.log, "no ranging for 2.0 s: tracking on the IMU alone")) << out.log;
  EXPECT_TRUE(contains(out.log, "ranging back after 30.0 s")) << out.log;
}

TEST(RilodFaults, DamagedSamplesAreDroppedCountedAndExplained) {
  testing::TempDir dir("rilod-damaged");
  const std::string faults =
      "      - {kind: duplicate, at_s: 14, count: 50}\n"
      "      - {kind: out_of_order, at_s: 18, count: 40, stream: imu}\n"
      "      - {kind: non_finite, at_s: 22, count: 30}\n"
      "      - {kind: imu_gap, at_s: 26, duration_s: 0.15}\n"
      "      - {kind: imu_gap, at_s: 30, duration_s: 0.3}\n";
  const RilodOutput out = testing::runRilod(dir, config(officeDemo(), faults), 0.0, 60s);
  std::printf("rilod damaged-samples run: %.1f s wall, %zu odometry, %zu status received\n", out.wall_s,
              out.odometry.size(), out.status.size());
  ASSERT_EQ(out.exit_code, 0) << out.log;
  ASSERT_FALSE(out.status.empty());

  const dds::StatusMessage& last = lastStatus(out);
  EXPECT_EQ(last.status.duplicate_samples, 50u);
  EXPECT_EQ(last.status.out_of_order_samples, 40u);
  EXPECT_EQ(last.status.non_finite_samples, 30u);
  EXPECT_EQ(last.status.imu_gaps, 2u);
  EXPECT_EQ(last.status.reinitializations, 0u) << "no fault reached the estimator";
  EXPECT_TRUE(trackingApartFromLoad(last)) << "status trail:\n" << statusTrail(out);
  // Each one was reported as the reason of a degraded state while it happened
  // (a burst may straddle two status periods: the counts are checked above).
  for (const char* why : {"duplicated sample", "out-of-order sample", "non-finite sample", "IMU gap"}) {
    EXPECT_NE(findStatus(out, "degraded", why), nullptr) << why << "\nstatus trail:\n" << statusTrail(out);
  }
  // Odometry never repeated, went back in time or carried a NaN.
  expectOdometryClean(out);
  EXPECT_GT(last.status.published_odometry, 20'000u);
  // The status line in the log carries the counters and the reason.
  EXPECT_TRUE(contains(out.log, "dropped non-finite 30, duplicate 50, out-of-order 40")) << out.log;
}

TEST(RilodFaults, ImpossibleValuesAreScreenedCountedAndExplainedWhileTracking) {
  // Issue 37: ranges of -5 and 1e9 m and accelerations of 1e30 m/s^2 were
  // fused without a word. The estimator's screen drops them; the status
  // topic, its reason and the log say so; tracking goes on.
  testing::TempDir dir("rilod-impossible");
  const std::string faults =
      "      - {kind: impossible, at_s: 16, count: 12, stream: ranging}\n"
      "      - {kind: impossible, at_s: 24, count: 7, stream: imu}\n";
  const RilodOutput out = testing::runRilod(dir, config(officeDemo(), faults), 0.0, 60s);
  ASSERT_EQ(out.exit_code, 0) << out.log;
  ASSERT_FALSE(out.status.empty());
  const dds::StatusMessage& last = lastStatus(out);
  EXPECT_EQ(last.status.out_of_bounds_samples, 12u);
  EXPECT_EQ(last.status.beyond_full_scale_samples, 7u);
  EXPECT_EQ(last.status.far_future_samples, 0u);
  EXPECT_EQ(last.status.reinitializations, 0u) << "no impossible value reached the estimator";
  EXPECT_TRUE(trackingApartFromLoad(last)) << "status trail:\n" << statusTrail(out);
  for (const char* why : {"out-of-bounds value", "beyond full scale"}) {
    EXPECT_NE(findStatus(out, "degraded", why), nullptr) << why << "\nstatus trail:\n" << statusTrail(out);
  }
  expectOdometryClean(out);
  // Nor did they reach the odometry, extrapolated from the IMU at IMU rate
  // (the entrance screens them before the publisher sees them).
  for (const auto& o : out.odometry) ASSERT_LT(o.p_w_b.norm(), 1e3) << "an impossible IMU sample reached the odometry";
  EXPECT_TRUE(contains(out.log, "screened out-of-bounds 12, beyond-full-scale 7, far-future 0")) << out.log;
}

TEST(RilodFaults, FarFutureStampsAreDroppedAndTheStreamsGoOn) {
  // Issue 37 (and the review of its first fix): a stamp 28 years ahead
  // became the stream's last one at the entrance, and every real sample
  // after it was "out of order". Now each is dropped and the streams go on.
  testing::TempDir dir("rilod-far-future");
  const std::string faults =
      "      - {kind: far_future, at_s: 16, count: 1, stream: imu}\n"
      "      - {kind: far_future, at_s: 20, count: 1, stream: ranging}\n"
      "      - {kind: far_future, at_s: 24, count: 1, stream: imu}\n";
  const RilodOutput out = testing::runRilod(dir, config(officeDemo(), faults), 0.0, 60s);
  ASSERT_EQ(out.exit_code, 0) << out.log;
  ASSERT_FALSE(out.status.empty());
  const dds::StatusMessage& last = lastStatus(out);
  EXPECT_EQ(last.status.far_future_samples, 3u);
  EXPECT_EQ(last.status.out_of_order_samples, 0u);
  EXPECT_EQ(last.status.time_jumps, 0u);
  EXPECT_EQ(last.status.reinitializations, 0u) << last.status.last_fault.data();
  EXPECT_TRUE(trackingApartFromLoad(last)) << "status trail:\n" << statusTrail(out);
  EXPECT_NE(findStatus(out, "degraded", "far-future sample"), nullptr) << "status trail:\n" << statusTrail(out);
  expectOdometryClean(out);
}

TEST(RilodFaults, LongImuGapLosesTrackingStopsOdometryAndReinitializes) {
  testing::TempDir dir("rilod-imu-gap");
  const RilodOutput out =
      testing::runRilod(dir, config(officeDemo(), "      - {kind: imu_gap, at_s: 17, duration_s: 1.5}\n"), 0.0, 60s);
  std::printf("rilod long-IMU-gap run: %.1f s wall, %zu odometry, %zu status received\n", out.wall_s,
              out.odometry.size(), out.status.size());
  ASSERT_EQ(out.exit_code, 0) << out.log;
  ASSERT_FALSE(out.status.empty());
  // More than LocalizerParams::max_imu_gap_s (1 s): the motion model is broken, tracking is lost.
  // The entrance holds the first three samples after the gap until they
  // confirm the step (input_screen.max_imu_jump_s): the gap the tracker
  // sees is 1.5 s + one period (1.25 ms) + three held samples (3.75 ms).
  const dds::StatusMessage* lost = findStatus(out, "lost", "IMU silent for 1.51 s");
  ASSERT_NE(lost, nullptr) << "status trail:\n" << statusTrail(out);
  EXPECT_TRUE(contains(reasonOf(*lost), "; initializing")) << reasonOf(*lost);
  const dds::StatusMessage& last = lastStatus(out);
  EXPECT_TRUE(trackingApartFromLoad(last)) << "status trail:\n" << statusTrail(out);
  EXPECT_EQ(last.status.reinitializations, 1u);
  EXPECT_EQ(last.status.far_future_samples, 3u);
  EXPECT_EQ(last.status.time_jumps, 1u);
  // While lost the service published no odometry (it would be dead reckoning
  // from a state it declared wrong): the longest pause in the received
  // stamps is the re-initialization, after the gap.
  expectOdometryClean(out);
  const std::int64_t t0 = readRecording(officeDemo()).imu.front().t_ns;
  std::int64_t longest = 0, longest_from = 0;
  for (std::size_t i = 1; i < out.odometry.size(); ++i) {
    const std::int64_t pause = out.odometry[i].stamp_ns - out.odometry[i - 1].stamp_ns;
    if (pause > longest) {
      longest = pause;
      longest_from = out.odometry[i - 1].stamp_ns;
    }
  }
  EXPECT_GT(longest, 5'000'000'000) << "no odometry while re-initializing";
  EXPECT_GE(longest_from - t0, 17'000'000'000 - 1'300'000'000) << "the pause starts at the gap (a queue early at most)";
  EXPECT_TRUE(contains(out.log, "tracking lost: IMU silent for 1.51 s")) << out.log;
}

}  // namespace
}  // namespace rilo
