// Write -> read round trips of every recording file, and the writer's
// streaming, flushing and refusal behaviour.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <thread>

#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"
#include "hal/recording/recording_writer.h"
#include "recording_test_util.h"

namespace rilo {
namespace {

using testing::readText;
using testing::TempDir;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Same double, bit for bit (so -0.0 != 0.0); any NaN equals any NaN.
bool same(double a, double b) {
  if (std::isnan(a) || std::isnan(b)) return std::isnan(a) && std::isnan(b);
  return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b);
}
bool same(const Vec3& a, const Vec3& b) { return same(a.x(), b.x()) && same(a.y(), b.y()) && same(a.z(), b.z()); }
bool same(const std::optional<double>& a, const std::optional<double>& b) {
  return a.has_value() == b.has_value() && (!a || same(*a, *b));
}
bool same(const std::optional<Vec3>& a, const std::optional<Vec3>& b) {
  return a.has_value() == b.has_value() && (!a || same(*a, *b));
}

void expectSame(const Recording& a, const Recording& b) {
  EXPECT_EQ(a.meta.name, b.meta.name);
  EXPECT_EQ(a.meta.description, b.meta.description);
  EXPECT_TRUE(same(a.meta.gravity_m_s2, b.meta.gravity_m_s2));
  EXPECT_TRUE(same(a.meta.imu_rate_hz, b.meta.imu_rate_hz));
  EXPECT_TRUE(same(a.meta.gyro_noise_density, b.meta.gyro_noise_density));
  EXPECT_TRUE(same(a.meta.accel_noise_density, b.meta.accel_noise_density));
  EXPECT_TRUE(same(a.meta.gyro_bias_random_walk, b.meta.gyro_bias_random_walk));
  EXPECT_TRUE(same(a.meta.accel_bias_random_walk, b.meta.accel_bias_random_walk));
  EXPECT_TRUE(same(a.meta.uwb_lever_arm_m, b.meta.uwb_lever_arm_m));
  EXPECT_TRUE(same(a.meta.ultrasonic_lever_arm_m, b.meta.ultrasonic_lever_arm_m));
  EXPECT_EQ(a.meta.ranging, b.meta.ranging);

  ASSERT_EQ(a.anchors.size(), b.anchors.size());
  for (std::size_t i = 0; i < a.anchors.size(); ++i) {
    EXPECT_EQ(a.anchors[i].id, b.anchors[i].id);
    EXPECT_TRUE(same(a.anchors[i].p_w_anchor, b.anchors[i].p_w_anchor)) << "anchor " << i;
    EXPECT_EQ(a.anchors[i].kind, b.anchors[i].kind);
    EXPECT_TRUE(same(a.anchors[i].sigma_m, b.anchors[i].sigma_m));
  }
  ASSERT_EQ(a.tags.size(), b.tags.size());
  for (std::size_t i = 0; i < a.tags.size(); ++i) {
    EXPECT_EQ(a.tags[i].id, b.tags[i].id);
    EXPECT_TRUE(same(a.tags[i].p_b_tag, b.tags[i].p_b_tag));
  }
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (std::size_t i = 0; i < a.imu.size(); ++i) {
    EXPECT_EQ(a.imu[i].t_ns, b.imu[i].t_ns);
    EXPECT_TRUE(same(a.imu[i].gyro_rad_s, b.imu[i].gyro_rad_s)) << "imu " << i;
    EXPECT_TRUE(same(a.imu[i].accel_m_s2, b.imu[i].accel_m_s2)) << "imu " << i;
  }
  ASSERT_EQ(a.imu_temp_c.size(), b.imu_temp_c.size());
  for (std::size_t i = 0; i < a.imu_temp_c.size(); ++i) EXPECT_TRUE(same(a.imu_temp_c[i], b.imu_temp_c[i]));
  ASSERT_EQ(a.ranges.size(), b.ranges.size());
  for (std::size_t i = 0; i < a.ranges.size(); ++i) {
    const RangeSample& x = a.ranges[i];
    const RangeSample& y = b.ranges[i];
    EXPECT_EQ(x.t_ns, y.t_ns);
    EXPECT_EQ(x.anchor_id, y.anchor_id);
    EXPECT_EQ(x.tag_id, y.tag_id);
    EXPECT_TRUE(same(x.range_m, y.range_m));
    EXPECT_TRUE(same(x.rssi_dbm, y.rssi_dbm));
    EXPECT_TRUE(same(x.fp_power_dbm, y.fp_power_dbm));
    EXPECT_EQ(x.los, y.los);
  }
  ASSERT_EQ(a.tdoa.size(), b.tdoa.size());
  for (std::size_t i = 0; i < a.tdoa.size(); ++i) {
    EXPECT_EQ(a.tdoa[i].t_ns, b.tdoa[i].t_ns);
    EXPECT_EQ(a.tdoa[i].anchor_a, b.tdoa[i].anchor_a);
    EXPECT_EQ(a.tdoa[i].anchor_b, b.tdoa[i].anchor_b);
    EXPECT_TRUE(same(a.tdoa[i].diff_m, b.tdoa[i].diff_m));
    EXPECT_TRUE(same(a.tdoa[i].rssi_a_dbm, b.tdoa[i].rssi_a_dbm));
    EXPECT_TRUE(same(a.tdoa[i].fp_power_a_dbm, b.tdoa[i].fp_power_a_dbm));
    EXPECT_TRUE(same(a.tdoa[i].rssi_b_dbm, b.tdoa[i].rssi_b_dbm));
    EXPECT_TRUE(same(a.tdoa[i].fp_power_b_dbm, b.tdoa[i].fp_power_b_dbm));
    EXPECT_EQ(a.tdoa[i].los, b.tdoa[i].los);
  }
  ASSERT_EQ(a.ultrasonic.size(), b.ultrasonic.size());
  for (std::size_t i = 0; i < a.ultrasonic.size(); ++i) {
    EXPECT_EQ(a.ultrasonic[i].t_ns, b.ultrasonic[i].t_ns);
    EXPECT_EQ(a.ultrasonic[i].anchor_id, b.ultrasonic[i].anchor_id);
    EXPECT_TRUE(same(a.ultrasonic[i].range_m, b.ultrasonic[i].range_m));
    EXPECT_EQ(a.ultrasonic[i].los, b.ultrasonic[i].los);
  }
  ASSERT_EQ(a.groundtruth.size(), b.groundtruth.size());
  for (std::size_t i = 0; i < a.groundtruth.size(); ++i) {
    const GroundTruthPose& x = a.groundtruth[i];
    const GroundTruthPose& y = b.groundtruth[i];
    EXPECT_EQ(x.t_ns, y.t_ns);
    EXPECT_TRUE(same(x.p_w_b, y.p_w_b));
    EXPECT_TRUE(same(x.q_w_b.w(), y.q_w_b.w()) && same(x.q_w_b.x(), y.q_w_b.x()) && same(x.q_w_b.y(), y.q_w_b.y()) &&
                same(x.q_w_b.z(), y.q_w_b.z()))
        << "groundtruth " << i;
    EXPECT_TRUE(same(x.v_w_b, y.v_w_b));
  }
}

/// Doubles that stress shortest round-trip formatting.
double trickyDouble(std::mt19937& rng) {
  static const double kSpecial[] = {0.1,  1.0 / 3.0, -0.0, 1e-300, 5e-324, 2.2250738585072014e-308,
                                    1.7976931348623157e308, 9.81, -123456.789, 1e22, 0.30000000000000004};
  std::uniform_int_distribution<int> pick(0, 3);
  if (pick(rng) == 0) {
    return kSpecial[std::uniform_int_distribution<std::size_t>(0, std::size(kSpecial) - 1)(rng)];
  }
  std::normal_distribution<double> n(0.0, 10.0);
  return n(rng);
}

Recording makeRecording(std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Recording r;
  r.meta.name = "office \"loop\" 3";
  r.meta.description = "two tags, ultrasonic beacons\nsecond line: with: colons, #hash";
  r.meta.gravity_m_s2 = 9.80665;
  r.meta.imu_rate_hz = 400.0;
  r.meta.gyro_noise_density = 1.7e-4;
  r.meta.accel_noise_density = 2e-3;
  r.meta.gyro_bias_random_walk = 1.9393e-05;
  r.meta.accel_bias_random_walk = 3.0e-3;
  r.meta.uwb_lever_arm_m = Vec3(0.1, -0.02, 1.0 / 3.0);
  r.meta.ultrasonic_lever_arm_m = Vec3(-0.0, 0.05, 0.2);
  r.meta.ranging = RangingKind::kDsTwr;

  for (std::uint32_t i = 0; i < 4; ++i) {
    Anchor a;
    a.id = 100 + i;
    a.p_w_anchor = Vec3(trickyDouble(rng), trickyDouble(rng), 2.5 + u(rng));
    if (i % 2 == 0) a.sigma_m = 0.01 * (i + 1);
    r.anchors.push_back(a);
  }
  for (std::uint32_t i = 0; i < 2; ++i) {
    Anchor a;
    a.id = 4000000000u + i;  // ids are uint32: use the top of the range
    a.p_w_anchor = Vec3(u(rng), u(rng), 3.0);
    a.kind = AnchorKind::kUltrasonic;
    r.anchors.push_back(a);
  }
  r.tags = {Tag{0, Vec3(0.1, 0.0, 0.3)}, Tag{7, Vec3(-0.1, 1e-17, 0.3)}};

  const std::int64_t t0 = 9'000'000'000'000'000'000;  // near the top of int64: exact integers required
  for (int k = 0; k < 500; ++k) {
    ImuSample s;
    s.t_ns = t0 + k * 2'500'000 + (k % 3);
    s.gyro_rad_s = Vec3(trickyDouble(rng), trickyDouble(rng), trickyDouble(rng));
    s.accel_m_s2 = Vec3(trickyDouble(rng), trickyDouble(rng), trickyDouble(rng));
    r.imu.push_back(s);
    r.imu_temp_c.push_back(k % 7 == 0 ? kNaN : 25.0 + u(rng));
  }
  for (int k = 0; k < 200; ++k) {
    const std::int64_t t = t0 + k * 10'000'000;
    // Several ranges share a timestamp: different anchors and tags.
    for (std::uint32_t j = 0; j < 3; ++j) {
      RangeSample s;
      s.t_ns = t;
      s.anchor_id = 100 + (static_cast<std::uint32_t>(k) + j) % 4;
      s.tag_id = j == 2 ? 7 : 0;
      s.range_m = 5.0 + trickyDouble(rng);
      s.rssi_dbm = k % 5 == 0 ? kNaN : -80.0 + u(rng);
      s.fp_power_dbm = k % 3 == 0 ? kNaN : -85.0 + u(rng);
      s.los = k % 4 == 0 ? -1 : (k % 4 == 1 ? 0 : 1);
      r.ranges.push_back(s);
    }
    TdoaSample d;
    d.t_ns = t + 1;
    d.anchor_a = 100;
    d.anchor_b = 101 + static_cast<std::uint32_t>(k) % 3;
    d.diff_m = trickyDouble(rng);
    d.rssi_a_dbm = k % 5 == 1 ? kNaN : -80.0 + u(rng);
    d.fp_power_a_dbm = k % 5 == 1 ? kNaN : -85.0 + u(rng);
    d.rssi_b_dbm = k % 7 == 2 ? kNaN : -80.0 + trickyDouble(rng);
    d.fp_power_b_dbm = k % 3 == 0 ? kNaN : -85.0 + u(rng);
    d.los = k % 3 - 1;
    r.tdoa.push_back(d);
    UltrasonicSample us;
    us.t_ns = t + 5;
    us.anchor_id = 4000000000u + static_cast<std::uint32_t>(k) % 2;
    us.range_m = 3.0 + u(rng);
    us.los = k % 2;
    r.ultrasonic.push_back(us);
    GroundTruthPose g;
    g.t_ns = t + 3;
    g.p_w_b = Vec3(trickyDouble(rng), trickyDouble(rng), u(rng));
    g.q_w_b = Quat(u(rng), u(rng), u(rng), u(rng)).normalized();
    if (k % 2 == 0) g.v_w_b = Vec3(u(rng), u(rng), u(rng));
    r.groundtruth.push_back(g);
  }
  return r;
}

TEST(RecordingRoundTrip, EveryFileTypeReadsBackIdentical) {
  TempDir dir;
  const Recording original = makeRecording(1);
  writeRecording(dir.path(), original);
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kTagsFile, recording::kImuFile,
                             recording::kRangeFile, recording::kTdoaFile, recording::kUltrasonicFile,
                             recording::kGroundTruthFile}) {
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  }
  ReadReport report;
  const Recording back = readRecording(dir.path(), &report);
  EXPECT_TRUE(report.warnings.empty()) << report.warnings.front().message;
  EXPECT_EQ(report.skipped_rows, 0u);
  expectSame(original, back);

  // And a second generation writes byte-identical files.
  TempDir dir2;
  writeRecording(dir2.path(), back);
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kImuFile,
                             recording::kRangeFile, recording::kGroundTruthFile}) {
    EXPECT_EQ(readText(dir / f), readText(dir2 / f)) << f;
  }
}

TEST(RecordingRoundTrip, MinimalRecordingWithoutOptionalFiles) {
  TempDir dir;
  Recording r;
  r.anchors.push_back(Anchor{1, Vec3(1, 2, 3), AnchorKind::kUwb, std::nullopt});
  ImuSample s;
  s.t_ns = -5;  // the clock is any monotonic clock: negative times are legal
  s.accel_m_s2 = Vec3(0, 0, 9.81);
  r.imu.push_back(s);
  writeRecording(dir.path(), r);
  EXPECT_FALSE(std::filesystem::exists(dir / recording::kRangeFile));
  EXPECT_FALSE(std::filesystem::exists(dir / recording::kTagsFile));
  ReadReport report;
  const Recording back = readRecording(dir.path(), &report);
  EXPECT_TRUE(report.warnings.empty());
  expectSame(r, back);
  EXPECT_TRUE(back.imu_temp_c.empty());
  ASSERT_TRUE(back.findTagLeverArm(0).has_value());  // no tags.csv: one antenna at uwb.lever_arm
  EXPECT_FALSE(back.findTagLeverArm(1).has_value());
}

TEST(RecordingRoundTrip, WriterHeadersUseTheFormatColumns) {
  TempDir dir;
  writeRecording(dir.path(), makeRecording(2));
  auto firstLine = [&](std::string_view f) {
    const std::string t = readText(dir / f);
    return t.substr(0, t.find('\n'));
  };
  EXPECT_EQ(firstLine(recording::kAnchorsFile), "id,x,y,z,kind,sigma");
  EXPECT_EQ(firstLine(recording::kTagsFile), "id,x,y,z");
  EXPECT_EQ(firstLine(recording::kImuFile), "t_ns,wx,wy,wz,ax,ay,az,temp_c");
  EXPECT_EQ(firstLine(recording::kRangeFile), "t_ns,anchor_id,range_m,tag_id,rssi_dbm,fp_power_dbm,los");
  EXPECT_EQ(firstLine(recording::kTdoaFile),
            "t_ns,anchor_a,anchor_b,diff_m,rssi_a_dbm,fp_power_a_dbm,rssi_b_dbm,fp_power_b_dbm,los");
  EXPECT_EQ(firstLine(recording::kUltrasonicFile), "t_ns,anchor_id,range_m,los");
  // '#' first: evo's EuRoC reader (numpy, comments='#') would read the header as a row of data.
  EXPECT_EQ(firstLine(recording::kGroundTruthFile), "#t_ns,px,py,pz,qw,qx,qy,qz,vx,vy,vz");
}

TEST(RecordingRoundTrip, GroundTruthQuaternionIsWFirstOnDisk) {
  TempDir dir;
  Recording r;
  GroundTruthPose g;
  g.t_ns = 1;
  g.q_w_b = Quat(0.5, -0.5, 0.5, -0.5);  // Eigen: w first
  r.groundtruth.push_back(g);
  writeRecording(dir.path(), r);
  const std::string text = readText(dir / recording::kGroundTruthFile);
  EXPECT_NE(text.find("\n1,0,0,0,0.5,-0.5,0.5,-0.5,,,\n"), std::string::npos) << text;
  const Recording back = readRecording(dir.path());
  ASSERT_EQ(back.groundtruth.size(), 1u);
  EXPECT_EQ(back.groundtruth[0].q_w_b.w(), 0.5);
  EXPECT_EQ(back.groundtruth[0].q_w_b.x(), -0.5);
  EXPECT_TRUE(back.groundtruth[0].pose().R.isApprox(g.q_w_b.toRotationMatrix(), 1e-15));
}

TEST(RecordingWriter, EmptyWriterLeavesAReadableRecording) {
  TempDir dir;
  {
    RecordingWriter w(dir / "rec");
    w.close();
  }
  ReadReport report;
  const Recording r = readRecording(dir / "rec", &report);
  EXPECT_TRUE(r.anchors.empty());
  EXPECT_TRUE(r.imu.empty());
  EXPECT_TRUE(report.warnings.empty());
}

TEST(RecordingWriter, FlushedPrefixIsReadableWhileStillWriting) {
  TempDir dir;
  RecordingWriterOptions opt;
  opt.flush_every_records = 0;  // only explicit flushes
  opt.flush_interval_ms = 0;
  RecordingWriter w(dir.path(), opt);
  w.writeAnchors({Anchor{3, Vec3(0, 0, 2), AnchorKind::kUwb, std::nullopt}});
  for (int k = 0; k < 100; ++k) {
    ImuSample s;
    s.t_ns = k * 1000;
    s.gyro_rad_s = Vec3(0.1 * k, 0, 0);
    w.write(s);
    RangeSample r;
    r.t_ns = k * 1000;
    r.anchor_id = 3;
    r.range_m = 1.0 + k;
    w.write(r);
  }
  // Nothing flushed yet: the stream files do not even have a header on disk.
  EXPECT_EQ(readText(dir / recording::kImuFile), "");
  w.flush();
  for (int k = 100; k < 150; ++k) {
    ImuSample s;
    s.t_ns = k * 1000;
    w.write(s);
  }
  ReadReport report;
  const Recording r = readRecording(dir.path(), &report);
  EXPECT_EQ(r.imu.size(), 100u);
  EXPECT_EQ(r.ranges.size(), 100u);
  EXPECT_TRUE(report.warnings.empty());
  w.close();
  EXPECT_EQ(readRecording(dir.path()).imu.size(), 150u);
  EXPECT_EQ(w.recordsWritten(), 250u);
}

TEST(RecordingWriter, TimeTriggerFlushesOnTheNextWrite) {
  TempDir dir;
  RecordingWriterOptions opt;
  opt.flush_every_records = 0;
  opt.flush_interval_ms = 5;
  RecordingWriter w(dir.path(), opt);
  ImuSample s;
  s.t_ns = 1;
  w.write(s);
  // Sleeping longer than the interval makes the next write flush: no timing
  // assertion, only the order of events.
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  s.t_ns = 2;
  w.write(s);
  std::vector<ImuSample> imu;
  std::vector<double> temp;
  ReadReport rep;
  recording::parseImu(readText(dir / recording::kImuFile), "imu.csv", imu, temp, rep);
  EXPECT_EQ(imu.size(), 2u);
  w.close();
}

TEST(RecordingWriter, KilledChildLeavesPrefixUpToLastFlush) {
  TempDir dir;
  constexpr int kFlushEvery = 64;
  constexpr int kSamples = 1000;
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    int rc = 0;
    try {
      RecordingWriterOptions opt;
      opt.flush_every_records = kFlushEvery;
      opt.flush_interval_ms = 0;
      auto* w = new RecordingWriter(dir.path(), opt);  // never deleted: the "crash" skips every destructor
      w->writeAnchors({Anchor{1, Vec3(0, 0, 2), AnchorKind::kUwb, std::nullopt}});
      for (int k = 0; k < kSamples; ++k) {
        ImuSample s;
        s.t_ns = 1'000'000 * k;
        s.accel_m_s2 = Vec3(0.001 * k, 0, 9.81);
        w->write(s);
        if (k % 10 == 0) {
          RangeSample r;
          r.t_ns = s.t_ns;
          r.anchor_id = 1;
          r.range_m = 2.0 + 0.01 * k;
          w->write(r);
        }
      }
    } catch (...) {
      rc = 1;
    }
    ::_exit(rc);  // no close(), no flush of the last partial interval
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);

  ReadReport report;
  const Recording r = readRecording(dir.path(), &report);
  EXPECT_TRUE(report.warnings.empty());
  // Records counted over both streams: 1000 imu + 100 range = 1100; the last
  // flush happened after record 17 * 64 = 1088.
  const std::size_t flushed = (kSamples + kSamples / 10) / kFlushEvery * kFlushEvery;
  EXPECT_EQ(r.imu.size() + r.ranges.size(), flushed);
  EXPECT_GT(r.imu.size(), 900u);
  for (std::size_t k = 0; k < r.imu.size(); ++k) {
    EXPECT_EQ(r.imu[k].t_ns, static_cast<std::int64_t>(1'000'000 * k));
    EXPECT_EQ(r.imu[k].accel_m_s2.x(), 0.001 * static_cast<double>(k));
  }
  const std::string imu_text = readText(dir / recording::kImuFile);
  ASSERT_FALSE(imu_text.empty());
  EXPECT_EQ(imu_text.back(), '\n');  // whole lines only
}

TEST(RecordingWriter, RefusesWhatTheReaderWouldReject) {
  TempDir dir;
  RecordingWriter w(dir.path());
  RangeSample r;
  r.anchor_id = 1;
  EXPECT_THROW(w.write(r), std::logic_error);  // anchors first
  w.writeAnchors({Anchor{1, Vec3(0, 0, 2), AnchorKind::kUwb, std::nullopt},
                  Anchor{2, Vec3(1, 0, 2), AnchorKind::kUltrasonic, std::nullopt}});
  EXPECT_THROW(w.writeAnchors({}), std::logic_error);

  ImuSample s;
  s.t_ns = 10;
  w.write(s);
  EXPECT_THROW(w.write(s), std::invalid_argument);  // equal t_ns
  s.t_ns = 5;
  EXPECT_THROW(w.write(s), std::invalid_argument);  // backwards
  s.t_ns = 20;
  s.gyro_rad_s.y() = kNaN;
  EXPECT_THROW(w.write(s), std::invalid_argument);
  s.gyro_rad_s.y() = 0.0;
  EXPECT_THROW(w.write(s, 20.0), std::invalid_argument);  // no temp_c column
  w.write(s);                                              // a refused sample left no trace

  r.t_ns = 10;
  r.range_m = 3.0;
  w.write(r);
  r.anchor_id = 2;  // an ultrasonic anchor
  EXPECT_THROW(w.write(r), std::invalid_argument);
  r.anchor_id = 9;
  EXPECT_THROW(w.write(r), std::invalid_argument);
  r.anchor_id = 1;
  EXPECT_THROW(w.write(r), std::invalid_argument);  // same t_ns and ids
  r.tag_id = 3;
  r.t_ns = 11;
  EXPECT_THROW(w.write(r), std::invalid_argument);  // unknown tag (no tags.csv: only 0)
  r.tag_id = 0;
  r.los = 2;
  EXPECT_THROW(w.write(r), std::invalid_argument);
  r.los = 1;
  r.rssi_dbm = std::numeric_limits<double>::infinity();
  EXPECT_THROW(w.write(r), std::invalid_argument);
  r.rssi_dbm = kNaN;
  w.write(r);
  EXPECT_THROW(w.writeTags({Tag{0, Vec3::Zero()}}), std::logic_error);  // after ranges

  GroundTruthPose g;
  g.q_w_b = Quat(2, 0, 0, 0);
  EXPECT_THROW(w.write(g), std::invalid_argument);

  RecordingMeta meta;
  meta.gravity_m_s2 = -9.81;
  EXPECT_THROW(w.writeMeta(meta), std::invalid_argument);
  w.close();
  EXPECT_THROW(w.write(s), std::logic_error);

  const Recording back = readRecording(dir.path());
  EXPECT_EQ(back.imu.size(), 2u);
  EXPECT_EQ(back.ranges.size(), 2u);
  EXPECT_FALSE(std::filesystem::exists(dir / recording::kMetaFile));
}

TEST(RecordingWriter, RefusesToOverwriteUnlessAsked) {
  TempDir dir;
  writeRecording(dir.path(), makeRecording(3));
  EXPECT_THROW(writeRecording(dir.path(), makeRecording(3)), std::system_error);
  RecordingWriterOptions opt;
  opt.overwrite = true;
  Recording small;
  small.anchors.push_back(Anchor{5, Vec3(0, 0, 0), AnchorKind::kUwb, 0.5});
  writeRecording(dir.path(), small, opt);
  EXPECT_FALSE(std::filesystem::exists(dir / recording::kRangeFile));  // no stale stream from the old recording
  EXPECT_FALSE(std::filesystem::exists(dir / recording::kTagsFile));
  const Recording back = readRecording(dir.path());
  ASSERT_EQ(back.anchors.size(), 1u);
  EXPECT_EQ(back.anchors[0].id, 5u);
  EXPECT_TRUE(back.imu.empty());
}

TEST(RecordingWriter, SyncOptionWritesTheSameBytes) {
  TempDir a;
  TempDir b;
  const Recording r = makeRecording(4);
  writeRecording(a.path(), r);
  RecordingWriterOptions opt;
  opt.sync = true;
  opt.flush_every_records = 100;
  writeRecording(b.path(), r, opt);
  EXPECT_EQ(readText(a / recording::kImuFile), readText(b / recording::kImuFile));
  EXPECT_EQ(readText(a / recording::kRangeFile), readText(b / recording::kRangeFile));
}

}  // namespace
}  // namespace rilo
