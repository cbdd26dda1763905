// Recorder: samples pushed from producer threads land in a recording folder
// that reads back identically; flushed data survives a crash (a forked child
// that _exit()s without closing anything); bad samples and full queues are
// counted, never fatal.
#include "rilod/recorder.h"

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "hal/recording/recording_reader.h"
#include "rilod/config.h"
#include "rilod/recorder_config.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

using testing::TempDir;

constexpr std::int64_t kT0 = 5'000'000'000;
constexpr std::int64_t kImuPeriod = 1'250'000;  // 800 Hz

ImuSample imuAt(int i) {
  ImuSample s;
  s.t_ns = kT0 + i * kImuPeriod;
  s.gyro_rad_s = Eigen::Vector3d(0.01 * i, -0.02, 0.125 + 1e-7 * i);
  s.accel_m_s2 = Eigen::Vector3d(0.1, 0.2 * std::sin(i), 9.81);
  return s;
}

RangeSample rangeAt(int i) {
  RangeSample r;
  r.t_ns = kT0 + std::int64_t{i} * 25'000'000;
  r.anchor_id = static_cast<std::uint32_t>(i % 4);
  r.range_m = 3.0 + 0.001 * i;
  r.rssi_dbm = -80.5;
  return r;
}

RecordingSetup setup() {
  RecordingSetup s;
  s.meta.name = "recorder-test";
  s.meta.gyro_noise_density = 1.4e-4;
  s.meta.uwb_lever_arm_m = Vec3(0.01, 0.02, 0.03);
  for (std::uint32_t id = 0; id < 4; ++id) {
    Anchor a;
    a.id = id;
    a.p_w_anchor = Vec3(id, 2.0 * id, 2.5);
    s.anchors.push_back(a);
  }
  return s;
}

RecorderOptions fastOptions() {
  RecorderOptions o;
  o.flush_interval_ns = 20'000'000;
  o.poll_period_ns = 1'000'000;
  o.queue_capacity = 1 << 16;
  return o;
}

template <typename Done>
bool waitFor(Done done, std::chrono::seconds deadline = std::chrono::seconds(20)) {
  const auto end = std::chrono::steady_clock::now() + deadline;
  while (!done() && std::chrono::steady_clock::now() < end) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return done();
}

std::size_t linesOnDisk(const std::filesystem::path& file) {
  const std::string text = testing::readFile(file);
  return static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
}

void expectSameImu(const ImuSample& a, const ImuSample& b) {
  EXPECT_EQ(a.t_ns, b.t_ns);
  EXPECT_EQ(a.gyro_rad_s, b.gyro_rad_s);
  EXPECT_EQ(a.accel_m_s2, b.accel_m_s2);
}

TEST(RecorderTest, SamplesReadBackIdentically) {
  TempDir dir;
  const auto rec_dir = dir / "rec";
  {
    Recorder recorder(rec_dir, setup(), 2, fastOptions());
    EXPECT_EQ(recorder.dir(), rec_dir);
    for (int i = 0; i < 400; ++i) recorder.channel(0).push(imuAt(i));
    for (int i = 0; i < 20; ++i) recorder.channel(1).push(rangeAt(i));
    recorder.channel(1).fault(SourceFault{kT0, "/dev/spidev0.0", "RX timeout", false});
    recorder.close();
    const RecorderCounters c = recorder.counters();
    EXPECT_EQ(c.written, 420u);
    EXPECT_EQ(c.dropped_full, 0u);
    EXPECT_EQ(c.rejected, 0u);
    EXPECT_EQ(c.faults, 1u);
    EXPECT_FALSE(recorder.failed());
    EXPECT_EQ(recorder.error(), "");
  }
  ReadReport report;
  const Recording rec = readRecording(rec_dir, &report);
  EXPECT_TRUE(report.warnings.empty());
  EXPECT_EQ(rec.meta.name, "recorder-test");
  ASSERT_TRUE(rec.meta.gyro_noise_density.has_value());
  EXPECT_DOUBLE_EQ(*rec.meta.gyro_noise_density, 1.4e-4);
  EXPECT_EQ(rec.meta.uwb_lever_arm_m, Vec3(0.01, 0.02, 0.03));
  ASSERT_EQ(rec.anchors.size(), 4u);
  EXPECT_EQ(rec.anchors[3].p_w_anchor, Vec3(3.0, 6.0, 2.5));
  ASSERT_EQ(rec.imu.size(), 400u);
  for (int i = 0; i < 400; ++i) expectSameImu(rec.imu[static_cast<std::size_t>(i)], imuAt(i));
  ASSERT_EQ(rec.ranges.size(), 20u);
  for (int i = 0; i < 20; ++i) {
    const RangeSample& r = rec.ranges[static_cast<std::size_t>(i)];
    EXPECT_EQ(r.t_ns, rangeAt(i).t_ns);
    EXPECT_EQ(r.anchor_id, rangeAt(i).anchor_id);
    EXPECT_EQ(r.range_m, rangeAt(i).range_m);
    EXPECT_EQ(r.rssi_dbm, -80.5);
  }
}

TEST(RecorderTest, ExplicitFlushSurvivesACrash) {
  TempDir dir;
  const auto rec_dir = dir / "rec";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    // The "service": records, flushes, then dies without closing anything.
    auto* recorder = new Recorder(rec_dir, setup(), 2, fastOptions());  // never deleted: a crash
    for (int i = 0; i < 1000; ++i) recorder->channel(0).push(imuAt(i));
    for (int i = 0; i < 40; ++i) recorder->channel(1).push(rangeAt(i));
    recorder->flush();
    ::_exit(recorder->counters().written == 1040 ? 0 : 3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);

  ReadReport report;
  const Recording rec = readRecording(rec_dir, &report);
  EXPECT_EQ(report.skipped_rows, 0u);
  ASSERT_EQ(rec.imu.size(), 1000u);
  expectSameImu(rec.imu.back(), imuAt(999));
  EXPECT_EQ(rec.ranges.size(), 40u);
  EXPECT_EQ(rec.anchors.size(), 4u);
}

TEST(RecorderTest, PeriodicFlushBoundsWhatACrashLoses) {
  TempDir dir;
  const auto rec_dir = dir / "rec";
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    auto* recorder = new Recorder(rec_dir, setup(), 1, fastOptions());
    for (int i = 0; i < 500; ++i) recorder->channel(0).push(imuAt(i));
    // No flush() call: the time trigger alone must put them on disk.
    const bool on_disk = waitFor([&] { return linesOnDisk(rec_dir / "imu.csv") == 501; });  // header + 500
    // More samples, then an immediate crash: those may be lost, nothing else.
    for (int i = 500; i < 600; ++i) recorder->channel(0).push(imuAt(i));
    ::_exit(on_disk ? 0 : 3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0) << "the first 500 samples never reached the disk";

  ReadReport report;
  const Recording rec = readRecording(rec_dir, &report);
  ASSERT_GE(rec.imu.size(), 500u);
  ASSERT_LE(rec.imu.size(), 600u);
  for (std::size_t i = 0; i < rec.imu.size(); ++i) expectSameImu(rec.imu[i], imuAt(static_cast<int>(i)));
}

TEST(RecorderTest, BadSamplesAreCountedAndSkipped) {
  TempDir dir;
  Recorder recorder(dir / "rec", setup(), 2, fastOptions());
  recorder.channel(0).push(imuAt(0));
  recorder.channel(0).push(imuAt(2));
  recorder.channel(0).push(imuAt(1));  // back in time
  ImuSample nan = imuAt(3);
  nan.accel_m_s2.x() = std::numeric_limits<double>::quiet_NaN();
  recorder.channel(0).push(nan);
  recorder.channel(0).push(imuAt(4));
  RangeSample unknown = rangeAt(1);
  unknown.anchor_id = 99;  // not surveyed
  recorder.channel(1).push(rangeAt(0));
  recorder.channel(1).push(unknown);
  recorder.channel(1).push(rangeAt(0));  // duplicate
  TdoaSample tdoa;
  tdoa.t_ns = kT0;
  tdoa.anchor_a = 0;
  tdoa.anchor_b = 1;
  tdoa.diff_m = 0.5;
  recorder.channel(1).push(tdoa);
  recorder.close();

  const RecorderCounters c = recorder.counters();
  EXPECT_EQ(c.written, 5u);
  EXPECT_EQ(c.rejected, 4u);
  EXPECT_FALSE(recorder.failed());
  EXPECT_NE(recorder.error().find("first rejected sample: RecordingWriter"), std::string::npos) << recorder.error();

  const Recording rec = readRecording(dir / "rec");
  ASSERT_EQ(rec.imu.size(), 3u);
  EXPECT_EQ(rec.imu[2].t_ns, imuAt(4).t_ns);
  EXPECT_EQ(rec.ranges.size(), 1u);
  EXPECT_EQ(rec.tdoa.size(), 1u);
}

TEST(RecorderTest, FullQueueDropsInsteadOfBlocking) {
  TempDir dir;
  RecorderOptions options = fastOptions();
  options.queue_capacity = 16;
  Recorder recorder(dir / "rec", setup(), 1, options);
  constexpr int kPushed = 200'000;
  for (int i = 0; i < kPushed; ++i) recorder.channel(0).push(imuAt(i));
  recorder.close();
  const RecorderCounters c = recorder.counters();
  EXPECT_GT(c.dropped_full, 0u);
  EXPECT_EQ(c.written + c.dropped_full, static_cast<std::uint64_t>(kPushed));
  EXPECT_EQ(c.rejected, 0u);  // what got through is still in order
  EXPECT_EQ(readRecording(dir / "rec").imu.size(), c.written);
}

TEST(RecorderTest, ConcurrentProducersOnTheirOwnChannels) {
  TempDir dir;
  Recorder recorder(dir / "rec", setup(), 2, fastOptions());
  std::thread imu([&] {
    for (int i = 0; i < 20'000; ++i) {
      recorder.channel(0).push(imuAt(i));
      if (i % 1000 == 0) std::this_thread::yield();
    }
  });
  std::thread uwb([&] {
    for (int i = 0; i < 1'000; ++i) recorder.channel(1).push(rangeAt(i));
  });
  std::thread control([&] {
    for (int i = 0; i < 5; ++i) recorder.flush();
  });
  imu.join();
  uwb.join();
  control.join();
  recorder.close();
  const RecorderCounters c = recorder.counters();
  EXPECT_EQ(c.dropped_full, 0u);
  EXPECT_EQ(c.written, 21'000u);
  EXPECT_EQ(c.flushes, 5u);
  const Recording rec = readRecording(dir / "rec");
  EXPECT_EQ(rec.imu.size(), 20'000u);
  EXPECT_EQ(rec.ranges.size(), 1'000u);
}

TEST(RecorderTest, RefusesAnExistingRecordingAndBadOptions) {
  TempDir dir;
  { Recorder first(dir / "rec", setup(), 1, fastOptions()); }
  EXPECT_ANY_THROW(Recorder(dir / "rec", setup(), 1, fastOptions()));
  EXPECT_THROW(Recorder(dir / "a", setup(), 0, fastOptions()), std::invalid_argument);
  RecorderOptions bad = fastOptions();
  bad.flush_interval_ns = 0;
  EXPECT_THROW(Recorder(dir / "b", setup(), 1, bad), std::invalid_argument);
  Recorder ok(dir / "c", setup(), 1, fastOptions());
  EXPECT_THROW(ok.channel(1), std::out_of_range);
}

TEST(RecorderTest, CloseIsIdempotentAndFlushAfterCloseReturns) {
  TempDir dir;
  Recorder recorder(dir / "rec", setup(), 1, fastOptions());
  recorder.channel(0).push(imuAt(0));
  recorder.close();
  recorder.close();
  recorder.flush();
  EXPECT_EQ(readRecording(dir / "rec").imu.size(), 1u);
}

TEST(RecorderTest, EmptyRecordingStillReadsBack) {
  TempDir dir;
  { Recorder recorder(dir / "rec", setup(), 1, fastOptions()); }
  const Recording rec = readRecording(dir / "rec");
  EXPECT_TRUE(rec.imu.empty());
  EXPECT_EQ(rec.anchors.size(), 4u);
}

TEST(RecorderTest, TeeSinkForwardsToBoth) {
  struct Counting final : SampleSink {
    int samples = 0, faults = 0, notes = 0;
    void push(const Sample&) noexcept override { ++samples; }
    void fault(const SourceFault&) noexcept override { ++faults; }
    void note(const SourceNote&) noexcept override { ++notes; }
  } a, b;
  TeeSink tee(a, b);
  tee.push(imuAt(0));
  tee.push(rangeAt(0));
  tee.fault(SourceFault{});
  tee.note(SourceNote{});
  EXPECT_EQ(a.samples, 2);
  EXPECT_EQ(b.samples, 2);
  EXPECT_EQ(a.faults, 1);
  EXPECT_EQ(b.faults, 1);
  EXPECT_EQ(a.notes, 1);  // rilod's recording keeps the device notes in the log
  EXPECT_EQ(b.notes, 1);
}

TEST(RecordingDirectoryTest, NamedByUtcTimeAndNeverShared) {
  TempDir dir;
  // 2024-01-02 03:04:05 UTC
  const auto t = std::chrono::system_clock::time_point(std::chrono::seconds(1704164645));
  const auto first = newRecordingDirectory(dir / "recordings", t);
  EXPECT_EQ(first, dir / "recordings" / "rilod-20240102-030405");
  EXPECT_TRUE(std::filesystem::is_directory(first));
  const auto second = newRecordingDirectory(dir / "recordings", t);
  EXPECT_EQ(second, dir / "recordings" / "rilod-20240102-030405-2");
  // A recorder writes into the fresh, empty folder.
  Recorder recorder(second, setup(), 1, fastOptions());
  recorder.close();
  EXPECT_TRUE(std::filesystem::exists(second / "anchors.csv"));
}

TEST(RecorderConfigTest, SetupAndOptionsFollowTheServiceConfig) {
  TempDir dir;
  const std::string yaml =
      "sources: {mode: replay, replay: {path: rec}}\n"
      "anchors:\n"
      "  - {id: 0, x: 0, y: 0, z: 2.5}\n"
      "  - {id: 1, x: 6, y: 0, z: 1.0}\n"
      "  - {id: 2, x: 6, y: 5, z: 2.5}\n"
      "imu: {gyro_noise_density: 3.0e-4, gravity_m_s2: 9.8}\n"
      "estimator: {range: {lever_arm_m: [0.1, 0.0, 0.2]}}\n"
      "recording: {enabled: true, directory: recs, flush_interval_s: 0.1, sync: true}\n"
      "realtime: {queue_capacity: 512}\n";
  const ServiceConfig config = parseServiceConfig(yaml, dir / "rilod.yaml");
  const RecorderOptions o = recorderOptions(config);
  EXPECT_EQ(o.flush_interval_ns, 100'000'000);
  EXPECT_TRUE(o.sync);
  EXPECT_EQ(o.queue_capacity, 512u);
  const RecordingSetup s = recordingSetup(config);
  EXPECT_EQ(s.anchors.size(), 3u);
  ASSERT_TRUE(s.meta.gyro_noise_density.has_value());
  EXPECT_DOUBLE_EQ(*s.meta.gyro_noise_density, 3.0e-4);
  EXPECT_DOUBLE_EQ(s.meta.gravity_m_s2, 9.8);
  EXPECT_EQ(s.meta.uwb_lever_arm_m, Vec3(0.1, 0.0, 0.2));
  EXPECT_FALSE(s.meta.ranging.has_value());  // replay: unknown

  // The setup is one the writer accepts.
  Recorder recorder(newRecordingDirectory(config.recording.directory), s, 1, o);
  recorder.close();
  EXPECT_FALSE(recorder.failed());
}

// A board whose DW3000 is configured with a tag id other than 0 stamps its
// ranges with it: the recording lists that antenna (tags.csv) so the writer
// takes them, and a replay predicts them from its lever arm.
TEST(RecorderConfigTest, AHardwareTagIdIsListedWithItsLeverArm) {
  ServiceConfig config = loadServiceConfig(testing::sourceDir() / "config" / "rilod-hardware.yaml");
  ASSERT_EQ(config.sources.mode, SourceMode::kHardware);
  EXPECT_TRUE(recordingSetup(config).tags.empty()) << "tag 0: the single antenna of meta.yaml";
  config.sources.hardware.uwb.dw3000.tag_id = 5;
  const RecordingSetup s = recordingSetup(config);
  ASSERT_EQ(s.tags.size(), 1u);
  EXPECT_EQ(s.tags[0].id, 5u);
  EXPECT_EQ(s.tags[0].p_b_tag, config.estimator.graph.p_b_tag);

  testing::TempDir dir("rilo-recorder-tag");
  Recorder recorder(newRecordingDirectory(dir / "recs"), s, 1, RecorderOptions{});
  RangeSample r;
  r.t_ns = 1'000'000;
  r.anchor_id = config.anchors.front().id;
  r.tag_id = 5;
  r.range_m = 3.0;
  recorder.channel(0).push(Sample{r});
  recorder.close();
  EXPECT_FALSE(recorder.failed()) << recorder.error();
  EXPECT_EQ(recorder.counters().written, 1u);
  EXPECT_EQ(recorder.counters().rejected, 0u) << recorder.error();
}

}  // namespace
}  // namespace rilo
