// `rilo record`'s logic: the hardware sources built from a configuration on
// the DW3000 and BMI263 emulators, recorded by runRecordSession into a folder
// that reads back with the configuration's anchors and meta, every sample
// accounted for; a stop request, a failing source and bad arguments.
#include "rilod/record_session.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <mutex>
#include <thread>

#include "hal/recording/recording_reader.h"
#include "rilod/config.h"
#include "rilod/hardware_sources.h"
#include "rilod/recorder_config.h"
#include "service/emulated_board.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

using testing::BoardTruth;
using testing::EmulatedBoard;
using testing::TempDir;
using testing::TimeLimitedSource;

constexpr std::int64_t kS = 1'000'000'000;
// Device nodes no machine has (the configuration insists on /dev/ paths).
constexpr const char* kMissingSpi = "/dev/rilo-test-no-spidev9.9";
constexpr const char* kMissingI2c = "/dev/rilo-test-no-i2c-9";

class RecordSessionTest : public ::testing::Test {
 protected:
  RecordSessionTest() {
    testing::writeBlob(dir_ / "blob.bin");
    truth_.responders[0] = {2.5, 15.0};
    truth_.responders[1] = {4.0, -20.0};
    truth_.responders[2] = {7.25, 0.0};
    truth_.responders[3] = {5.5, 5.0};
  }

  ServiceConfig config() { return parseServiceConfig(testing::boardYaml(), dir_ / "rilod.yaml"); }

  /// The two hardware sources on `board`, each ending after `seconds` of its virtual time.
  static std::vector<std::unique_ptr<SampleSource>> boardSources(const ServiceConfig& cfg, EmulatedBoard& board,
                                                                 double uwb_seconds, double imu_seconds) {
    auto sources = makeHardwareSources(cfg.sources.hardware, board.uwb(), board.imu());
    std::vector<std::unique_ptr<SampleSource>> limited;
    limited.push_back(std::make_unique<TimeLimitedSource>(std::move(sources[0]), board.uwbClock(),
                                                          static_cast<std::int64_t>(uwb_seconds * kS)));
    limited.push_back(std::make_unique<TimeLimitedSource>(std::move(sources[1]), board.imuClock(),
                                                          static_cast<std::int64_t>(imu_seconds * kS)));
    return limited;
  }

  static std::vector<SampleSource*> raw(const std::vector<std::unique_ptr<SampleSource>>& sources) {
    std::vector<SampleSource*> r;
    for (const auto& s : sources) r.push_back(s.get());
    return r;
  }

  TempDir dir_{"record"};
  BoardTruth truth_;
};

TEST_F(RecordSessionTest, RecordsTheEmulatedBoardIntoAReadableRecording) {
  const ServiceConfig cfg = config();
  EmulatedBoard board(cfg.sources.hardware, truth_);
  auto sources = boardSources(cfg, board, 2.0, 2.0);
  const RecorderOptions recorder_options = recorderOptions(cfg);
  EXPECT_EQ(recorder_options.flush_interval_ns, 200'000'000);  // the configuration's recording section
  Recorder recorder(dir_ / "rec", recordingSetup(cfg), sources.size(), recorder_options);
  std::atomic<bool> stop{false};
  std::mutex notes_mutex;
  std::vector<SourceNote> notes;
  RecordSessionCallbacks callbacks;
  callbacks.on_note = [&](const SourceNote& n) {
    const std::lock_guard<std::mutex> lock(notes_mutex);
    notes.push_back(n);
  };
  const RecordSessionResult result = runRecordSession(raw(sources), recorder, stop, {}, callbacks);

  EXPECT_EQ(result.exitCode(), 0);
  EXPECT_FALSE(result.interrupted);
  // Each device said once what its start-up read and applied (rilo record logs it).
  ASSERT_EQ(notes.size(), 2u);
  std::sort(notes.begin(), notes.end(), [](const auto& a, const auto& b) { return a.device < b.device; });
  EXPECT_EQ(notes[0].device, "emu:bmi263@0x68");  // the emulated buses' names
  EXPECT_EQ(notes[0].what.rfind("started: chip id 0x24", 0), 0u) << notes[0].what;
  EXPECT_NE(notes[0].what.find("blob.bin' loaded"), std::string::npos) << notes[0].what;
  EXPECT_EQ(notes[1].device, "emu:spidev0.0");
  EXPECT_EQ(notes[1].what.rfind("started: ", 0), 0u) << notes[1].what;
  EXPECT_NE(notes[1].what.find("PGF calibration done"), std::string::npos) << notes[1].what;
  EXPECT_NE(notes[1].what.find("part 0x"), std::string::npos) << notes[1].what;
  ASSERT_EQ(result.sources.size(), 2u);
  const SourceTally& uwb = result.sources[0];
  const SourceTally& imu = result.sources[1];
  EXPECT_EQ(uwb.end, SourceEnd::kStopped);
  EXPECT_EQ(imu.end, SourceEnd::kStopped);
  EXPECT_NE(uwb.name.find("dwm3000"), std::string::npos) << uwb.name;
  EXPECT_EQ(uwb.imu, 0u);
  EXPECT_EQ(imu.ranges, 0u);
  // Four anchors at 10 Hz for 2 s; 800 Hz for 2 s.
  EXPECT_NEAR(static_cast<double>(uwb.ranges), 80.0, 6.0);
  // (The IMU's 2 s include its bring-up: blob upload and sensor start-up, ~80 ms.)
  EXPECT_GE(imu.imu, 1500u);
  EXPECT_LE(imu.imu, 1601u);
  EXPECT_EQ(uwb.faults + imu.faults, 0u) << uwb.last_fault << imu.last_fault;
  EXPECT_EQ(result.recorder.written, uwb.ranges + imu.imu);
  EXPECT_EQ(result.recorder.dropped_full + result.recorder.dropped_failed + result.recorder.rejected, 0u);
  EXPECT_FALSE(result.recorder_failed);

  const Recording rec = readRecording(dir_ / "rec");
  EXPECT_EQ(rec.imu.size(), imu.imu);
  EXPECT_EQ(rec.ranges.size(), uwb.ranges);
  ASSERT_EQ(rec.anchors.size(), 4u);
  EXPECT_EQ(rec.anchors[1].p_w_anchor, Vec3(6.0, 0.0, 1.0));
  ASSERT_TRUE(rec.meta.imu_rate_hz.has_value());
  EXPECT_DOUBLE_EQ(*rec.meta.imu_rate_hz, 800.0);
  ASSERT_TRUE(rec.meta.ranging.has_value());
  EXPECT_EQ(*rec.meta.ranging, RangingKind::kSsTwr);
  std::map<std::uint32_t, int> per_anchor;
  for (const RangeSample& r : rec.ranges) {
    ++per_anchor[r.anchor_id];
    EXPECT_NEAR(r.range_m, truth_.responders[r.anchor_id].distance_m, 0.01) << r.anchor_id;
  }
  for (std::uint32_t id = 0; id < 4; ++id) EXPECT_GE(per_anchor[id], 18) << id;
  ASSERT_GT(rec.imu.size(), 1u);
  const double imu_span_s = static_cast<double>(rec.imu.back().t_ns - rec.imu.front().t_ns) * 1e-9;
  EXPECT_NEAR(static_cast<double>(rec.imu.size() - 1) / imu_span_s, 800.0, 1.0);
  for (std::size_t i = 1; i < rec.imu.size(); ++i) {
    ASSERT_GT(rec.imu[i].t_ns, rec.imu[i - 1].t_ns);
    EXPECT_NEAR(rec.imu[i].accel_m_s2.z(), 9.80665, 0.2);
  }
}

/// Never ends by itself: pushes an IMU sample every millisecond of wall time.
class EndlessSource final : public SampleSource {
 public:
  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override {
    std::int64_t t_ns = 1'000'000'000;
    while (!stop.load()) {
      ImuSample s;
      s.t_ns = t_ns += 1'250'000;
      s.accel_m_s2 = Eigen::Vector3d(0.0, 0.0, 9.81);
      sink.push(s);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return SourceEnd::kStopped;
  }
  std::string describe() const override { return "endless"; }
};

TEST_F(RecordSessionTest, AStopRequestEndsTheSessionAndKeepsTheRecording) {
  const ServiceConfig cfg = config();
  EndlessSource endless;
  Recorder recorder(dir_ / "rec", recordingSetup(cfg), 1, recorderOptions(cfg));
  std::atomic<bool> stop{false};
  std::thread stopper([&stop] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stop.store(true);
  });
  int progress_calls = 0;
  RecordSessionOptions options;
  options.progress_period_ns = 20'000'000;
  RecordSessionCallbacks callbacks;
  callbacks.on_progress = [&progress_calls](const std::vector<SourceTally>& tallies, const RecorderCounters&) {
    ASSERT_EQ(tallies.size(), 1u);
    ++progress_calls;
  };
  const RecordSessionResult result = runRecordSession({&endless}, recorder, stop, options, callbacks);
  stopper.join();
  EXPECT_TRUE(result.interrupted);
  EXPECT_EQ(result.exitCode(), 0);
  EXPECT_GE(progress_calls, 1);  // no upper bound: the machine may be loaded
  ASSERT_EQ(result.sources.size(), 1u);
  EXPECT_GT(result.sources[0].imu, 0u);
  EXPECT_EQ(readRecording(dir_ / "rec").imu.size(), result.sources[0].imu);
}

TEST_F(RecordSessionTest, AFailingSourceStopsTheOthersAndTheRecordingStaysReadable) {
  const ServiceConfig cfg = config();
  truth_.chip_id = 0x55;  // the BMI263 bring-up fails for good (wrong chip id)
  EmulatedBoard board(cfg.sources.hardware, truth_);
  auto sources = makeHardwareSources(cfg.sources.hardware, board.uwb(), board.imu());
  EndlessSource endless;  // stands in for a UWB source that would run for ever
  Recorder recorder(dir_ / "rec", recordingSetup(cfg), 2, recorderOptions(cfg));
  std::atomic<bool> stop{false};
  std::vector<SourceFault> faults;
  std::mutex mutex;
  RecordSessionCallbacks callbacks;
  callbacks.on_fault = [&](const SourceFault& f) {
    const std::lock_guard<std::mutex> lock(mutex);
    faults.push_back(f);
  };
  const RecordSessionResult result = runRecordSession({&endless, sources[1].get()}, recorder, stop, {}, callbacks);
  EXPECT_FALSE(result.interrupted);
  EXPECT_EQ(result.exitCode(), 1);
  EXPECT_EQ(result.sources[0].end, SourceEnd::kStopped);
  EXPECT_EQ(result.sources[1].end, SourceEnd::kFailed);
  EXPECT_EQ(result.sources[1].fatal_faults, 1u);
  EXPECT_NE(result.sources[1].last_fault.find("emu:bmi263@0x68"), std::string::npos) << result.sources[1].last_fault;
  ASSERT_FALSE(faults.empty());
  EXPECT_TRUE(faults.back().fatal);
  EXPECT_EQ(readRecording(dir_ / "rec").imu.size(), result.sources[0].imu);
}

TEST_F(RecordSessionTest, RejectsBadArguments) {
  const ServiceConfig cfg = config();
  EndlessSource endless;
  Recorder recorder(dir_ / "rec", recordingSetup(cfg), 1, recorderOptions(cfg));
  std::atomic<bool> stop{true};
  EXPECT_THROW(runRecordSession({}, recorder, stop), std::invalid_argument);
  EXPECT_THROW(runRecordSession({&endless, &endless}, recorder, stop), std::invalid_argument);  // one channel
  EXPECT_THROW(runRecordSession({nullptr}, recorder, stop), std::invalid_argument);
  RecordSessionOptions bad;
  bad.poll_period_ns = 0;
  EXPECT_THROW(runRecordSession({&endless}, recorder, stop, bad), std::invalid_argument);
}

TEST(HardwareSections, ToolsNeedTheHardwareMode) {
  TempDir dir("record");
  testing::writeBlob(dir / "blob.bin");
  std::string yaml = testing::boardYaml();
  yaml.replace(yaml.find("mode: hardware"), 14, "mode: replay\n  replay: {path: rec}");
  const ServiceConfig replay = parseServiceConfig(yaml, dir / "rilod.yaml");
  try {
    (void)requireHardwareSection(replay);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("sources.mode is replay"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("rilod.yaml"), std::string::npos) << e.what();
  }
  const ServiceConfig hardware = parseServiceConfig(testing::boardYaml(), dir / "rilod.yaml");
  EXPECT_EQ(requireHardwareSection(hardware).uwb.dw3000.anchors.size(), 4u);
}

TEST(HardwareSections, MissingBusesAreAnInvalidArgument) {
  TempDir dir("record");
  const ServiceConfig cfg = parseServiceConfig(testing::boardYaml(), dir / "rilod.yaml");
  EXPECT_THROW(makeUwbSource(cfg.sources.hardware.uwb, UwbBuses{}), std::invalid_argument);
  EXPECT_THROW(makeImuSource(cfg.sources.hardware.imu, ImuBuses{}), std::invalid_argument);
}

TEST(HardwareSections, OpeningAMissingNodeNamesItAndTheKey) {
  TempDir dir("record");
  std::string yaml = testing::boardYaml();
  yaml.replace(yaml.find("/dev/spidev0.0"), 14, kMissingSpi);
  yaml.replace(yaml.find("/dev/i2c-1"), 10, kMissingI2c);
  const ServiceConfig cfg = parseServiceConfig(yaml, dir / "rilod.yaml");
  LinuxHardware hw;
  try {
    hw.openUwb(cfg.sources.hardware.uwb, "test");
    FAIL() << "no exception";
  } catch (const HardwareOpenError& e) {
    EXPECT_EQ(e.device(), std::string(kMissingSpi));
    EXPECT_NE(std::string(e.what()).find(std::string(kMissingSpi)), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("sources.hardware.uwb.spi_device"), std::string::npos) << e.what();
  }
  try {
    hw.openImu(cfg.sources.hardware.imu, "test");
    FAIL() << "no exception";
  } catch (const HardwareOpenError& e) {
    EXPECT_EQ(e.device(), std::string(kMissingI2c) + "@0x68");
    EXPECT_NE(std::string(e.what()).find("sources.hardware.imu.i2c_device"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rilo
