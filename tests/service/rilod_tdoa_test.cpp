// rilod's Service with a source that also delivers UWB TDoA rows and
// ultrasonic ranges (the IMU-Ultrasonic-UWB paper's system): they are counted on the status and
// reach the estimator (more states, so more pose publications, than the same
// session without them); rows naming anchors or beacons the configuration
// does not know are counted but skipped, without ending tracking.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <string>
#include <cstdio>
#include <thread>
#include <vector>

#include "dds/participant.h"
#include "dds/subscriber.h"
#include "hal/recording/recording_reader.h"
#include "hal/source.h"
#include "rilod/service.h"
#include "service/support/vector_source.h"
#include "service_test_support.h"

namespace rilo {
namespace {

using namespace std::chrono_literals;

using testing::VectorSource;

std::int64_t timeOf(const Sample& s) {
  return std::visit([](const auto& v) { return v.t_ns; }, s);
}

struct Session {
  std::vector<Sample> samples;
  std::size_t ranges = 0, tdoa = 0, ultrasonic = 0;
  std::size_t deep_nlos = 0;  ///< rows whose packet b is deeper in NLOS than the default gate (15 dB)
};

const Vec3 kLeverArm(0.06, 0.0, 0.10);
const Vec3 kBeacon(5.0, 4.0, 3.0);  ///< ultrasonic beacon id 20
constexpr std::uint32_t kBeaconId = 20;

/// The demo office session (IMU and ranges); with `extra`, also exact TDoA
/// rows between consecutive anchors every 20 ms and ultrasonic ranges to one
/// beacon every 100 ms from the ground truth, plus a few rows naming an
/// unknown anchor or beacon.
/// With `deep_every` > 0, every deep_every-th row (of known anchors) reports
/// packet b 20 dB below its RX level at the first path: deep NLOS.
Session demoSession(const Recording& rec, bool extra, bool with_ranges = true, std::int64_t blackout_from_ns = 0,
                    std::int64_t blackout_to_ns = 0, std::size_t deep_every = 0) {
  Session out;
  const std::int64_t t_end = rec.imu.front().t_ns + 30'000'000'000;  // the first 30 s: initialization and 20 s of tracking
  for (const ImuSample& m : rec.imu) {
    if (m.t_ns < t_end) out.samples.push_back(m);
  }
  for (const RangeSample& r : rec.ranges) {
    if (with_ranges && r.t_ns < t_end) {
      out.samples.push_back(r);
      ++out.ranges;
    }
  }
  if (extra) {
    const std::vector<Vec3> anchors = uwbAnchorsById(rec.anchors);
    std::uint32_t a = 0;
    for (std::size_t g = 0; g < rec.groundtruth.size() && rec.groundtruth[g].t_ns < t_end; ++g) {  // 50 Hz truth: a row every 20 ms
      const GroundTruthPose& truth = rec.groundtruth[g];
      if (truth.t_ns >= blackout_from_ns && truth.t_ns < blackout_to_ns) continue;
      const Pose3 T = truth.pose();
      const Vec3 p_tag = T.R * kLeverArm + T.p;
      const std::uint32_t b = (a + 1) % static_cast<std::uint32_t>(anchors.size());
      TdoaSample d;
      d.t_ns = truth.t_ns + 1'000'000;  // clear of the ranges' states
      d.anchor_a = a;
      d.anchor_b = g % 97 == 50 ? 99 : b;  // now and then an anchor rilod does not know
      d.diff_m = (p_tag - anchors[b]).norm() - (p_tag - anchors[a]).norm();
      if (deep_every > 0 && g % deep_every == 0 && d.anchor_b != 99) {
        d.rssi_a_dbm = -80.0;
        d.fp_power_a_dbm = -82.0;
        d.rssi_b_dbm = -85.0;
        d.fp_power_b_dbm = -105.0;
        ++out.deep_nlos;
      }
      out.samples.push_back(d);
      ++out.tdoa;
      a = b;
      if (g % 5 == 0) {
        UltrasonicSample u;
        u.t_ns = truth.t_ns + 2'000'000;
        u.anchor_id = g % 250 == 125 ? kBeaconId + 1 : kBeaconId;  // and a beacon it does not know
        u.range_m = (T.p - kBeacon).norm();  // receiver at the body origin
        out.samples.push_back(u);
        ++out.ultrasonic;
      }
    }
  }
  std::stable_sort(out.samples.begin(), out.samples.end(),
                   [](const Sample& x, const Sample& y) { return timeOf(x) < timeOf(y); });
  return out;
}

struct RunResult {
  ServiceStatus status;
  std::size_t poses = 0;
  std::vector<std::string> events;
  int exit_code = -1;
};

RunResult runService(const Recording& rec, const Session& session, std::uint32_t domain,
                     std::int64_t tdoa_state_window_ns = LocalizerParams().with_tdoa.state_window_ns) {
  ServiceOptions so;
  so.localizer.with_tdoa.state_window_ns = tdoa_state_window_ns;
  so.p_w_anchors = uwbAnchorsById(rec.anchors);
  so.localizer.graph.p_b_tag = kLeverArm;
  so.localizer.graph.p_w_ultrasonic.assign(kBeaconId + 1, Vec3::Constant(1e6));
  so.localizer.graph.p_w_ultrasonic[kBeaconId] = kBeacon;
  so.participant.domain_id = domain;
  so.participant.config_xml = dds::loopbackConfigXml();
  so.backpressure = true;
  so.status_period_s = 0.05;
  RunResult out;
  so.on_event = [&out](const std::string& e) { out.events.push_back(e); };
  dds::ParticipantOptions po;
  po.domain_id = domain;
  po.config_xml = dds::loopbackConfigXml();
  dds::Participant participant(po);
  dds::Subscriber subscriber(participant);

  std::vector<std::unique_ptr<SampleSource>> sources;
  sources.push_back(std::make_unique<VectorSource>(session.samples));
  Service service(so, std::move(sources));
  std::atomic<bool> stop{false}, done{false};
  std::thread runner([&] {
    out.exit_code = service.run(stop);
    done.store(true);
  });
  std::vector<dds::PoseMessage> poses;
  while (!done.load()) {
    subscriber.waitForData(20ms);
    subscriber.takePose(poses);
  }
  runner.join();
  for (int i = 0; i < 20; ++i) {  // the last ones in flight
    subscriber.waitForData(20ms);
    subscriber.takePose(poses);
  }
  out.poses = poses.size();
  out.status = service.status();
  return out;
}

TEST(RilodTdoa, TdoaAndUltrasonicAreCountedAndReachTheEstimator) {
  const Recording rec = readRecording(testing::sourceDir() / "tests" / "data" / "office-demo");
  const Session plain = demoSession(rec, false);
  const Session extra = demoSession(rec, true);
  ASSERT_GT(extra.tdoa, 1000u);
  ASSERT_GT(extra.ultrasonic, 200u);
  ASSERT_EQ(extra.ranges, plain.ranges);
  const std::uint32_t domain = 100 + static_cast<std::uint32_t>((::getpid() + 7) % 130);

  const RunResult without = runService(rec, plain, domain);
  // With the graph's 5 ms state window (not with_tdoa's 25 ms, in which the
  // 40 Hz ranges and 50 Hz rows share states) the rows open states of their
  // own: the pose count shows that they reach the estimator.
  const RunResult with = runService(rec, extra, domain, 0);
  EXPECT_EQ(without.exit_code, 0);
  EXPECT_EQ(with.exit_code, 0);
  EXPECT_EQ(without.status.tdoa_samples, 0u);
  EXPECT_EQ(without.status.ultrasonic_samples, 0u);
  EXPECT_EQ(with.status.tdoa_samples, extra.tdoa);
  EXPECT_EQ(with.status.ultrasonic_samples, extra.ultrasonic);
  EXPECT_EQ(with.status.range_samples, extra.ranges);
  EXPECT_EQ(with.status.range_samples, without.status.range_samples);
  EXPECT_EQ(with.status.deep_nlos_tdoa_rows, 0u);  // no diagnostics: never gated
  // Unknown anchors and beacons were skipped, not fatal to tracking.
  EXPECT_EQ(with.status.reinitializations, 0u);
  // The TDoA rows (50/s) mostly open states of their own between the
  // ranges' 5 ms groups: well over the publications of the ranges alone.
  std::printf("poses published: %zu without TDoA/ultrasonic, %zu with\n", without.poses, with.poses);
  ASSERT_GT(without.poses, 200u);
  EXPECT_GT(static_cast<double>(with.poses), 1.3 * static_cast<double>(without.poses))
      << with.poses << " vs " << without.poses;
}

TEST(RilodTdoa, TdoaAloneInitializesAndItsBlackoutIsARangingGap) {
  // No two-way ranges at all: the service tracks on TDoA and ultrasonic
  // (initialized from them), and a 4 s pause of both is a ranging gap like a
  // pause of ranges would be.
  const Recording rec = readRecording(testing::sourceDir() / "tests" / "data" / "office-demo");
  const std::int64_t t0 = rec.imu.front().t_ns;
  const Session session = demoSession(rec, true, false, t0 + 20'000'000'000, t0 + 24'000'000'000);
  ASSERT_EQ(session.ranges, 0u);
  const RunResult run = runService(rec, session, 100 + static_cast<std::uint32_t>((::getpid() + 11) % 130));
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_EQ(run.status.range_samples, 0u);
  EXPECT_EQ(run.status.tdoa_samples, session.tdoa);
  EXPECT_GT(run.poses, 200u);
  EXPECT_EQ(run.status.ranging_gaps, 1u);
  const bool back = std::any_of(run.events.begin(), run.events.end(),
                                [](const std::string& e) { return e.rfind("ranging back after", 0) == 0; });
  EXPECT_TRUE(back);
  const bool initialized = std::any_of(run.events.begin(), run.events.end(),
                                       [](const std::string& e) { return e.rfind("initialized", 0) == 0; });
  EXPECT_TRUE(initialized);
}

TEST(RilodTdoa, RowsDeepInNlosAreCountedOnTheStatusAndTrackingGoesOn) {
  // Every 7th row says its packet b arrived 20 dB below its RX level at the
  // first path (over the default 15 dB gate): the service drops it and says
  // how many on its status, while initializing and while tracking.
  const Recording rec = readRecording(testing::sourceDir() / "tests" / "data" / "office-demo");
  const Session session = demoSession(rec, true, true, 0, 0, 7);
  ASSERT_GT(session.deep_nlos, 100u);
  const RunResult run = runService(rec, session, 100 + static_cast<std::uint32_t>((::getpid() + 13) % 130));
  EXPECT_EQ(run.exit_code, 0);
  EXPECT_EQ(run.status.tdoa_samples, session.tdoa);
  EXPECT_EQ(run.status.deep_nlos_tdoa_rows, session.deep_nlos);
  EXPECT_EQ(run.status.reinitializations, 0u);
  EXPECT_GT(run.poses, 200u);
}

}  // namespace
}  // namespace rilo
