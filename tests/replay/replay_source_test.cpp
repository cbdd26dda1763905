// ReplaySource: merge order, fast and paced replay (on a fake clock), time
// shift, stop flag, malformed recordings and reader warnings.
#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <string>
#include <variant>
#include <vector>

#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"
#include "hal/replay/replay_source.h"
#include "replay_test_util.h"
#include "sim/office_recording.h"

namespace rilo {
namespace {

using rilo::testing::fileText;
using rilo::testing::ScratchDir;
using rilo::testing::writeFileText;

std::int64_t timeOf(const Sample& s) {
  return std::visit([](const auto& m) { return m.t_ns; }, s);
}

/// Collects samples and faults; can raise `stop` after a number of samples.
class CollectingSink final : public SampleSink {
 public:
  explicit CollectingSink(std::atomic<bool>* stop = nullptr, std::size_t stop_after = 0, const std::int64_t* clock = nullptr)
      : stop_(stop), stop_after_(stop_after), clock_(clock) {}
  void push(const Sample& sample) noexcept override {
    samples.push_back(sample);
    if (clock_ != nullptr) push_clock.push_back(*clock_);
    if (stop_ != nullptr && samples.size() == stop_after_) stop_->store(true);
  }
  void fault(const SourceFault& f) noexcept override { faults.push_back(f); }

  std::vector<Sample> samples;
  std::vector<std::int64_t> push_clock;  ///< the fake clock at each push
  std::vector<SourceFault> faults;

 private:
  std::atomic<bool>* stop_;
  std::size_t stop_after_;
  const std::int64_t* clock_;
};

/// A fake CLOCK_MONOTONIC: sleeping advances it to the wake time (no real sleep).
struct FakeClock {
  std::int64_t now = 7'000'000'000;
  std::vector<std::int64_t> sleeps;  ///< requested wake times
  std::function<void()> on_sleep;

  void install(ReplayOptions& o) {
    o.now_ns = [this] { return now; };
    o.sleep_until_ns = [this](std::int64_t wake) {
      sleeps.push_back(wake);
      now = std::max(now, wake);
      if (on_sleep) on_sleep();
    };
  }
};

/// A small recording with every stream and ties at t = 20.
Recording tiedRecording() {
  Recording r;
  r.anchors = {{0, Vec3(0, 0, 2), AnchorKind::kUwb, {}},
               {1, Vec3(5, 0, 2), AnchorKind::kUwb, {}},
               {9, Vec3(0, 5, 2), AnchorKind::kUltrasonic, {}}};
  auto imu = [](std::int64_t t) {
    ImuSample m;
    m.t_ns = t;
    return m;
  };
  r.imu = {imu(10), imu(20), imu(30)};
  RangeSample a;
  a.t_ns = 20;
  a.anchor_id = 0;
  RangeSample b = a;
  b.anchor_id = 1;
  RangeSample c = a;
  c.t_ns = 25;
  r.ranges = {a, b, c};
  TdoaSample d;
  d.t_ns = 20;
  d.anchor_a = 0;
  d.anchor_b = 1;
  r.tdoa = {d};
  UltrasonicSample u0, u1;
  u0.t_ns = 5;
  u0.anchor_id = 9;
  u1.t_ns = 20;
  u1.anchor_id = 9;
  r.ultrasonic = {u0, u1};
  return r;
}

/// A short simulated recording on disk.
void writeSimRecording(const std::filesystem::path& dir, double duration_s = 3.0) {
  sim::OfficeScenarioParams p;
  p.seed = 21;
  p.duration_s = duration_s;
  sim::writeOfficeRecording(p, dir);
}

TEST(ReplaySource, MergesStreamsInTimeOrderWithImuFirstOnTies) {
  ReplaySource src(tiedRecording(), "mem");
  CollectingSink sink;
  std::atomic<bool> stop{false};
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  ASSERT_EQ(sink.samples.size(), 9u);
  EXPECT_EQ(src.sampleCount(), 9u);
  // (time, variant index): imu 0, range 1, tdoa 2, ultrasonic 3.
  const std::vector<std::pair<std::int64_t, std::size_t>> want{{5, 3},  {10, 0}, {20, 0}, {20, 1}, {20, 1},
                                                               {20, 2}, {20, 3}, {25, 1}, {30, 0}};
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_EQ(timeOf(sink.samples[i]), want[i].first) << i;
    EXPECT_EQ(sink.samples[i].index(), want[i].second) << i;
  }
  // Within a file, the file order: anchor 0 before anchor 1 at t = 20.
  EXPECT_EQ(std::get<RangeSample>(sink.samples[3]).anchor_id, 0u);
  EXPECT_EQ(std::get<RangeSample>(sink.samples[4]).anchor_id, 1u);
  EXPECT_TRUE(sink.faults.empty());
  // Streams can be left out; a second run replays from the start.
  ReplayOptions only_ranges;
  only_ranges.imu = only_ranges.tdoa = only_ranges.ultrasonic = false;
  ReplaySource ranges(tiedRecording(), "mem", only_ranges);
  CollectingSink a, b;
  ranges.run(a, stop);
  ranges.run(b, stop);
  EXPECT_EQ(a.samples.size(), 3u);
  EXPECT_EQ(b.samples.size(), 3u);
}

TEST(ReplaySource, FastReplayOfARecordingGivesEverySampleOnceInOrder) {
  ScratchDir dir;
  writeSimRecording(dir.path());
  ReplaySource src(dir.path());
  EXPECT_EQ(src.describe(), "replay " + dir.path().string() + " (as fast as possible)");
  CollectingSink sink;
  std::atomic<bool> stop{false};
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  const Recording& rec = src.recording();
  ASSERT_EQ(sink.samples.size(), rec.imu.size() + rec.ranges.size());
  std::size_t imu = 0, ranges = 0;
  for (std::size_t i = 0; i < sink.samples.size(); ++i) {
    if (i > 0) {
      EXPECT_LE(timeOf(sink.samples[i - 1]), timeOf(sink.samples[i]));
    }
    if (const auto* m = std::get_if<ImuSample>(&sink.samples[i])) {
      EXPECT_EQ(m->t_ns, rec.imu[imu].t_ns);
      EXPECT_EQ(m->accel_m_s2, rec.imu[imu].accel_m_s2);
      ++imu;
    } else {
      const auto& r = std::get<RangeSample>(sink.samples[i]);
      EXPECT_EQ(r.range_m, rec.ranges[ranges].range_m);
      ++ranges;
    }
  }
  EXPECT_EQ(imu, rec.imu.size());
  EXPECT_EQ(ranges, rec.ranges.size());
  EXPECT_EQ(src.timeShiftNs(), 0);
}

TEST(ReplaySource, PacedReplayFollowsTheClockAtTheSpeedFactor) {
  ScratchDir dir;
  writeSimRecording(dir.path(), 1.0);
  FakeClock clock;
  ReplayOptions o;
  o.pacing = ReplayOptions::Pacing::kRealTime;
  o.speed = 2.0;
  o.max_sleep_ns = 1'000'000;
  clock.install(o);
  ReplaySource src(dir.path(), o);
  EXPECT_EQ(src.describe(), "replay " + dir.path().string() + " (paced x2)");
  CollectingSink sink(nullptr, 0, &clock.now);
  std::atomic<bool> stop{false};
  const std::int64_t start = clock.now;
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  ASSERT_EQ(sink.samples.size(), src.sampleCount());
  const std::int64_t t_first = timeOf(sink.samples.front());
  for (std::size_t i = 0; i < sink.samples.size(); ++i) {
    const std::int64_t due = start + (timeOf(sink.samples[i]) - t_first) / 2;
    // Pushed when due, not before, and (the fake sleep being exact) not later.
    EXPECT_GE(sink.push_clock[i], due - 1) << i;
    EXPECT_LE(sink.push_clock[i], due + 1) << i;
  }
  // The one-second recording took half a second of (fake) clock, in sleeps of at most 1 ms.
  EXPECT_NEAR(static_cast<double>(clock.now - start), 0.5e9, 1e3);
  ASSERT_FALSE(clock.sleeps.empty());
  std::int64_t before = start;
  for (std::int64_t wake : clock.sleeps) {
    EXPECT_LE(wake - before, o.max_sleep_ns);
    EXPECT_GT(wake, before);
    before = wake;
  }
  EXPECT_EQ(src.timeShiftNs(), 0);  // no shift asked for: recording times unchanged
}

TEST(ReplaySource, ShiftToNowMapsTheFirstSampleToTheStartTime) {
  FakeClock clock;
  ReplayOptions o;
  o.pacing = ReplayOptions::Pacing::kRealTime;
  o.shift_to_now = true;
  o.speed = 0.5;
  clock.install(o);
  ReplaySource src(tiedRecording(), "mem", o);
  EXPECT_EQ(src.describe(), "replay mem (paced x0.5, time shifted to now)");
  CollectingSink sink(nullptr, 0, &clock.now);
  std::atomic<bool> stop{false};
  const std::int64_t start = clock.now;
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  EXPECT_EQ(src.timeShiftNs(), start - 5);
  ASSERT_EQ(sink.samples.size(), 9u);
  EXPECT_EQ(timeOf(sink.samples.front()), start);
  // Time is shifted, never scaled: the recording's steps are kept at any speed.
  EXPECT_EQ(timeOf(sink.samples.back()), start + 25);
  EXPECT_EQ(sink.push_clock.back(), start + 50);  // but paced at half speed
}

TEST(ReplaySource, StopIsHonouredBetweenSamplesAndWhileSleeping) {
  std::atomic<bool> stop{false};
  {
    ReplaySource src(tiedRecording(), "mem");
    CollectingSink sink(&stop, 3);
    EXPECT_EQ(src.run(sink, stop), SourceEnd::kStopped);
    EXPECT_EQ(sink.samples.size(), 3u);
  }
  {
    stop = true;  // already set: nothing at all
    ReplaySource src(tiedRecording(), "mem");
    CollectingSink sink;
    EXPECT_EQ(src.run(sink, stop), SourceEnd::kStopped);
    EXPECT_TRUE(sink.samples.empty());
  }
  {
    // Paced, a 10 s gap between two samples; stop comes during the third slice of sleep.
    stop = false;
    Recording r;
    ImuSample a, b;
    a.t_ns = 0;
    b.t_ns = 10'000'000'000;
    r.imu = {a, b};
    FakeClock clock;
    ReplayOptions o;
    o.pacing = ReplayOptions::Pacing::kRealTime;
    o.max_sleep_ns = 20'000'000;
    clock.install(o);
    clock.on_sleep = [&] {
      if (clock.sleeps.size() == 3) stop = true;
    };
    ReplaySource src(r, "gap", o);
    CollectingSink sink;
    EXPECT_EQ(src.run(sink, stop), SourceEnd::kStopped);
    EXPECT_EQ(sink.samples.size(), 1u);
    EXPECT_EQ(clock.sleeps.size(), 3u);  // returned without sleeping again
  }
}

TEST(ReplaySource, MalformedRecordingThrowsAtConstructionWithFileLineColumn) {
  ScratchDir dir;
  writeSimRecording(dir.path(), 1.0);
  std::string ranges = fileText(dir / recording::kRangeFile);
  // Row 2 (line 3): the range becomes text.
  std::size_t line_start = 0;
  for (int line = 1; line < 3; ++line) line_start = ranges.find('\n', line_start) + 1;
  const std::size_t field = ranges.find(',', ranges.find(',', line_start) + 1) + 1;  // third column: range_m
  ranges.replace(field, ranges.find(',', field) - field, "far");
  writeFileText(dir / recording::kRangeFile, ranges);
  try {
    ReplaySource src(dir.path());
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_EQ(std::filesystem::path(e.file()).filename(), "range.csv");
    EXPECT_EQ(e.line(), 3u);
    EXPECT_EQ(e.column(), "range_m");
    EXPECT_NE(std::string(e.what()).find("range.csv:3: column 'range_m'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReplaySource(dir / "missing"), RecordingError);
}

TEST(ReplaySource, ReaderWarningsArriveAsNonFatalFaults) {
  ScratchDir dir;
  writeSimRecording(dir.path(), 1.0);
  // A logger that wrote an IMU row twice: the reader skips it with a warning.
  std::string imu = fileText(dir / recording::kImuFile);
  const std::size_t second = imu.find('\n') + 1, third = imu.find('\n', second) + 1;
  imu.insert(third, imu.substr(second, third - second));
  writeFileText(dir / recording::kImuFile, imu);
  ReplaySource src(dir.path());
  ASSERT_EQ(src.readReport().warnings.size(), 1u);
  CollectingSink sink;
  std::atomic<bool> stop{false};
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  ASSERT_EQ(sink.faults.size(), 1u);
  EXPECT_FALSE(sink.faults[0].fatal);
  // The log line is "device: what": the path and line once, in the message (issue 37).
  EXPECT_EQ(sink.faults[0].device, "replay");
  EXPECT_NE(sink.faults[0].what.find((dir.path() / "imu.csv").string() + ":3"), std::string::npos) << sink.faults[0].what;
  EXPECT_EQ(sink.samples.size(), src.recording().imu.size() + src.recording().ranges.size());
}

TEST(ReplaySource, BadOptionsThrow) {
  ReplayOptions o;
  o.speed = 0.0;
  EXPECT_THROW(ReplaySource(tiedRecording(), "mem", o), std::invalid_argument);
  o = ReplayOptions{};
  o.max_sleep_ns = 0;
  EXPECT_THROW(ReplaySource(tiedRecording(), "mem", o), std::invalid_argument);
}

TEST(ReplaySource, LoopReplaysAgainWithTimeRunningOn) {
  ReplayOptions o;
  o.loop = true;
  ReplaySource src(tiedRecording(), "mem", o);
  EXPECT_EQ(src.describe(), "replay mem (as fast as possible, looped)");
  // Span 5..30 ns plus the mean IMU period (10 ns).
  EXPECT_EQ(src.passPeriodNs(), 35);
  std::atomic<bool> stop{false};
  CollectingSink sink(&stop, 21);  // two passes and three samples of the third
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kStopped);
  ASSERT_EQ(sink.samples.size(), 21u);
  EXPECT_EQ(src.passes(), 3);
  for (std::size_t i = 9; i < sink.samples.size(); ++i) {
    const Sample& again = sink.samples[i];
    const Sample& once = sink.samples[i % 9];
    EXPECT_EQ(again.index(), once.index()) << i;
    EXPECT_EQ(timeOf(again), timeOf(once) + 35 * static_cast<std::int64_t>(i / 9)) << i;
    EXPECT_GE(timeOf(again), timeOf(sink.samples[i - 1])) << i;  // never back in time
  }
  // The seam: the last IMU sample of pass 0 (30) to the first of pass 1 (45).
  EXPECT_EQ(timeOf(sink.samples[8]), 30);
  EXPECT_EQ(timeOf(sink.samples[10]), 45);
  // Nothing to replay: the end of the data, not an endless loop.
  ReplaySource empty(Recording{}, "empty", o);
  CollectingSink none;
  EXPECT_EQ(empty.run(none, stop = false), SourceEnd::kEndOfData);
  EXPECT_EQ(empty.passes(), 0);
}

TEST(ReplaySource, PacedLoopStaysOnTheRecordingsSchedule) {
  FakeClock clock;
  ReplayOptions o;
  o.pacing = ReplayOptions::Pacing::kRealTime;
  o.shift_to_now = true;
  o.loop = true;
  clock.install(o);
  ReplaySource src(tiedRecording(), "mem", o);
  EXPECT_EQ(src.describe(), "replay mem (paced x1, time shifted to now, looped)");
  std::atomic<bool> stop{false};
  CollectingSink sink(&stop, 18, &clock.now);
  const std::int64_t start = clock.now;
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kStopped);
  ASSERT_EQ(sink.samples.size(), 18u);
  for (std::size_t i = 0; i < sink.samples.size(); ++i) {
    // Shifted to now and paced at speed 1: each sample is pushed at its own t_ns.
    EXPECT_EQ(sink.push_clock[i], timeOf(sink.samples[i])) << i;
  }
  EXPECT_EQ(timeOf(sink.samples.front()), start);
  EXPECT_EQ(timeOf(sink.samples[9]), start + 35);
}

TEST(ReplaySource, PacedOnTheRealClockRunsToTheEnd) {
  // Smoke test of the default clock and sleep (no timing assertion): 25 ns of
  // recording at speed 1 finish at once.
  ReplayOptions o;
  o.pacing = ReplayOptions::Pacing::kRealTime;
  o.shift_to_now = true;
  ReplaySource src(tiedRecording(), "mem", o);
  CollectingSink sink;
  std::atomic<bool> stop{false};
  EXPECT_EQ(src.run(sink, stop), SourceEnd::kEndOfData);
  EXPECT_EQ(sink.samples.size(), 9u);
  EXPECT_GT(src.timeShiftNs(), 0);
}

}  // namespace
}  // namespace rilo
