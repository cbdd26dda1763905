// rilo import-util: synthetic flights in the UTIL dataset's exact file layout
// (docs/util-dataset.md: wide CSV padded like zip_longest, ids written as
// floats, accelerometer in g, gyroscope in deg/s, tdoa = |p-A_idB| - |p-A_idA|,
// quaternions x,y,z,w; survey anN_p / anN_quat lines), generated from a
// LissajousWalk truth, imported, read back, and checked against the truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "hal/recording/number_text.h"
#include "hal/recording/recording_reader.h"
#include "import/physics_check.h"
#include "import/util_import.h"
#include "replay_test_util.h"
#include "sim/trajectory.h"

namespace rilo {
namespace {

using importer::AccelUnit;
using importer::CheckStatus;
using importer::GyroUnit;
using importer::TdoaSign;
using importer::UtilImport;
using importer::UtilImportOptions;

constexpr char kHeader[] =
    "t_tdoa,idA,idB,tdoa_meas,t_acc,acc_x,acc_y,acc_z,t_gyro,gyro_x,gyro_y,gyro_z,t_tof,tof,t_flow,deltaX,deltaY,"
    "t_baro,baro,t_pose,pose_x,pose_y,pose_z,pose_qx,pose_qy,pose_qz,pose_qw";

/// Anchors spread like a UTIL constellation (7 x 8 x 3 m arena, low/high alternating).
const std::vector<std::pair<std::uint32_t, Vec3>>& anchorPositions() {
  static const std::vector<std::pair<std::uint32_t, Vec3>> anchors = {
      {0, {-3.2, -3.6, 0.2}}, {1, {-3.0, 3.5, 2.6}}, {2, {3.4, 3.3, 0.2}},  {3, {3.4, -3.7, 2.6}},
      {4, {-3.3, -3.8, 2.6}}, {5, {3.3, -3.6, 0.2}}, {6, {3.6, 3.6, 2.6}}, {7, {-2.9, 3.2, 0.2}}};
  return anchors;
}

std::string surveyText() {
  std::string s;
  for (const auto& [id, p] : anchorPositions()) {
    s += "an" + std::to_string(id) + "_p,";
    recording::appendDouble(s, p.x());
    s += ',';
    recording::appendDouble(s, p.y());
    s += ',';
    recording::appendDouble(s, p.z());
    s += '\n';
  }
  for (const auto& [id, p] : anchorPositions()) {
    const Quat q(Eigen::AngleAxisd(0.3 * static_cast<double>(id), Vec3(0.2, 0.5, 1.0).normalized()));
    s += "an" + std::to_string(id) + "_quat,";
    recording::appendDouble(s, q.x());
    s += ',';
    recording::appendDouble(s, q.y());
    s += ',';
    recording::appendDouble(s, q.z());
    s += ',';
    recording::appendDouble(s, q.w());
    s += '\n';
  }
  return s;
}

std::string num(double v) {
  std::string s;
  recording::appendDouble(s, v);
  return s;
}

/// How the synthetic file is written (the dataset's conventions by default).
struct SynthSpec {
  double duration_s = 20.0;
  double imu_dt_s = 0.002;          ///< gyro and accel at 500 Hz
  double accel_offset_s = 0.0007;   ///< accelerometer times lag the gyro times
  double tdoa_dt_s = 0.01;          ///< TDoA2 round robin
  double pose_dt_s = 0.01;          ///< Vicon
  bool accel_in_g = true;
  bool gyro_in_deg = true;
  bool tdoa_flipped = false;        ///< file holds |p-A_idA| - |p-A_idB|
  Vec3 true_lever_arm = importer::kUtilTagLeverArm;
  double tdoa_noise_m = 0.0;
  std::map<std::pair<std::uint32_t, std::uint32_t>, double> pair_bias_m;
  double gravity = 9.81;
};

/// One stream block per vector: rows of fields.
struct UtilFile {
  std::string header = kHeader;
  std::vector<std::vector<std::string>> tdoa, acc, gyro, tof, flow, baro, pose;

  std::string text() const {
    const std::vector<std::pair<const std::vector<std::vector<std::string>>*, std::size_t>> blocks = {
        {&tdoa, 4}, {&acc, 4}, {&gyro, 4}, {&tof, 2}, {&flow, 3}, {&baro, 2}, {&pose, 8}};
    std::size_t rows = 0;
    for (const auto& [b, w] : blocks) rows = std::max(rows, b->size());
    std::string s = header + "\n";
    for (std::size_t k = 0; k < rows; ++k) {
      bool first = true;
      for (const auto& [b, w] : blocks) {
        for (std::size_t i = 0; i < w; ++i) {
          if (!first) s += ',';
          first = false;
          if (k < b->size()) s += (*b)[k][i];
        }
      }
      s += '\n';
    }
    return s;
  }
};

/// Line of row k of any block (the header is line 1).
std::size_t lineOf(std::size_t row) { return row + 2; }

sim::LissajousWalk::Params flightParams() {
  sim::LissajousWalk::Params p;
  p.center = Vec3(0.0, 0.0, 1.3);
  p.amplitude = Vec3(2.2, 2.6, 0.4);
  p.omega = Vec3(0.35, 0.45, 0.8);
  p.yaw_omega = 0.6;
  return p;
}

double truthTdoa(const sim::KinematicState& s, const Vec3& lever_arm, std::uint32_t a, std::uint32_t b) {
  const Vec3 p = s.T_w_b.p + s.T_w_b.R * lever_arm;
  const Vec3& A_a = anchorPositions()[a].second;
  const Vec3& A_b = anchorPositions()[b].second;
  return (p - A_b).norm() - (p - A_a).norm();
}

UtilFile synthesize(const SynthSpec& spec) {
  const sim::LissajousWalk walk(flightParams());
  UtilFile f;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  const auto steps = [](double duration, double dt) { return static_cast<std::size_t>(duration / dt); };

  for (std::size_t k = 0; k < steps(spec.duration_s, spec.imu_dt_s); ++k) {
    const double t_g = static_cast<double>(k) * spec.imu_dt_s;
    const sim::ImuReading g = sim::idealImu(walk.at(t_g), spec.gravity);
    const double gyro_scale = spec.gyro_in_deg ? 180.0 / std::numbers::pi : 1.0;
    f.gyro.push_back({num(t_g), num(g.gyro.x() * gyro_scale), num(g.gyro.y() * gyro_scale), num(g.gyro.z() * gyro_scale)});
    const double t_a = t_g + spec.accel_offset_s;
    const sim::ImuReading a = sim::idealImu(walk.at(t_a), spec.gravity);
    const double accel_scale = spec.accel_in_g ? 1.0 / spec.gravity : 1.0;
    f.acc.push_back({num(t_a), num(a.accel.x() * accel_scale), num(a.accel.y() * accel_scale),
                     num(a.accel.z() * accel_scale)});
  }
  for (std::size_t k = 0; k < steps(spec.duration_s, spec.tdoa_dt_s); ++k) {
    const double t = static_cast<double>(k) * spec.tdoa_dt_s + 0.0003;
    const std::uint32_t id_a = static_cast<std::uint32_t>((k + 7) % 8);  // TDoA2: (7,0), (0,1), ..., (6,7)
    const std::uint32_t id_b = static_cast<std::uint32_t>(k % 8);
    double d = truthTdoa(walk.at(t), spec.true_lever_arm, id_a, id_b) + spec.tdoa_noise_m * noise(rng);
    const auto bias = spec.pair_bias_m.find({id_a, id_b});
    if (bias != spec.pair_bias_m.end()) d += bias->second;
    if (spec.tdoa_flipped) d = -d;
    f.tdoa.push_back({num(t), std::to_string(id_a) + ".0", std::to_string(id_b) + ".0", num(d)});
  }
  for (std::size_t k = 0; k < steps(spec.duration_s, spec.pose_dt_s); ++k) {
    const double t = static_cast<double>(k) * spec.pose_dt_s + 0.0001;
    const Pose3 T = walk.at(t).T_w_b;
    const Quat q(T.R);
    f.pose.push_back({num(t), num(T.p.x()), num(T.p.y()), num(T.p.z()),
                      num(q.x()), num(q.y()), num(q.z()), num(q.w())});
  }
  for (std::size_t k = 0; k < 50; ++k) {
    const double t = 0.1 * static_cast<double>(k) + 0.05;
    f.tof.push_back({num(t), num(1.2)});
    f.flow.push_back({num(t), "3.0", "-2.0"});
    f.baro.push_back({num(t), num(81.5)});
  }
  return f;
}

UtilImport parse(const UtilFile& f, const UtilImportOptions& options = {}) {
  const importer::UtilSurvey survey = importer::parseUtilSurvey(surveyText(), "anchor_const1_survey.txt");
  return importer::parseUtilFlight(f.text(), "const1-trial1-tdoa2.csv", survey, options);
}

/// The RecordingError message of parsing `f`, or "" if it parsed.
std::string parseError(const UtilFile& f, const UtilImportOptions& options = {}) {
  try {
    parse(f, options);
  } catch (const RecordingError& e) {
    return e.what();
  }
  return "";
}

const importer::CheckVerdict& verdict(const std::vector<importer::CheckVerdict>& verdicts, const std::string& item) {
  const auto it = std::find_if(verdicts.begin(), verdicts.end(),
                               [&](const importer::CheckVerdict& v) { return v.item == item; });
  if (it == verdicts.end()) throw std::runtime_error("no verdict " + item);
  return *it;
}

std::vector<importer::CheckVerdict> judge(const UtilImport& im) {
  return importer::judgeUtilPhysics(importer::checkPhysics(im.recording), im.options);
}

bool sameRotation(const Quat& a, const Quat& b, double tol) {
  return std::abs(std::abs(a.normalized().dot(b.normalized())) - 1.0) < tol;
}

TEST(UtilImport, SurveyGivesAnchorPositionsById) {
  const importer::UtilSurvey s = importer::parseUtilSurvey(surveyText(), "survey.txt");
  ASSERT_EQ(s.anchors.size(), 8u);
  EXPECT_EQ(s.orientations, 8u);
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_EQ(s.anchors[i].id, i);
    EXPECT_EQ(s.anchors[i].kind, AnchorKind::kUwb);
    EXPECT_TRUE(s.anchors[i].p_w_anchor.isApprox(anchorPositions()[i].second, 1e-15));
  }
}

TEST(UtilImport, MalformedSurveyNamesFileAndLine) {
  const auto error = [](const std::string& text) {
    try {
      importer::parseUtilSurvey(text, "survey.txt");
    } catch (const RecordingError& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_NE(error("an0_p,1,2,3\nan1_pos,1,2,3\n").find("survey.txt:2:"), std::string::npos);
  EXPECT_NE(error("an0_p,1,2,3\nan1_p,1,2\n").find("survey.txt:2: column 'an1_p'"), std::string::npos);
  EXPECT_NE(error("an0_p,1,2,3\nan0_p,1,2,4\n").find("already has a position on line 1"), std::string::npos);
  EXPECT_NE(error("an0_p,1,abc,3\n").find("survey.txt:1: column 'y'"), std::string::npos);
  EXPECT_NE(error("an0_p,1,inf,3\n").find("survey.txt:1: column 'y'"), std::string::npos);
  EXPECT_NE(error("an0_p,1,2,3\nan1_quat,0,0,0,1\n").find("survey.txt:2:"), std::string::npos);
  EXPECT_NE(error("an0_p,1,2,3\nan0_quat,0,0,0,2\n").find("norm"), std::string::npos);
  EXPECT_NE(error("# only a comment\n").find("no anchor position"), std::string::npos);
  // Comments, blank lines and CRLF are fine.
  EXPECT_EQ(error("# survey\n\nan3_p,1,2,3\r\nan3_quat,0,0,0,1\r\n"), "");
}

TEST(UtilImport, ImportsSyntheticFlightAndReadsItBack) {
  const SynthSpec spec;
  const UtilFile file = synthesize(spec);
  testing::ScratchDir dir("util_import");
  testing::writeFileText(dir / "const1-trial1-tdoa2.csv", file.text());
  testing::writeFileText(dir / "anchor_const1_survey.txt", surveyText());
  const UtilImport im =
      importer::importUtil(dir / "const1-trial1-tdoa2.csv", dir / "anchor_const1_survey.txt", UtilImportOptions{});
  const Recording& rec = im.recording;

  // Counts: every sample kept; the first gyro sample (t = 0) precedes the first
  // accelerometer sample (0.7 ms) and has no interpolation partner.
  EXPECT_EQ(im.tdoa.rows, file.tdoa.size());
  EXPECT_EQ(im.tdoa.kept, file.tdoa.size());
  EXPECT_EQ(im.gyro.kept, file.gyro.size());
  EXPECT_EQ(im.accel.kept, file.acc.size());
  EXPECT_EQ(im.pose.kept, file.pose.size());
  EXPECT_EQ(im.tdoa.duplicates + im.gyro.duplicates + im.accel.duplicates + im.pose.duplicates, 0u);
  EXPECT_EQ(im.imu_without_partner, 1u);
  ASSERT_EQ(rec.imu.size(), file.gyro.size() - 1);
  ASSERT_EQ(rec.tdoa.size(), file.tdoa.size());
  ASSERT_EQ(rec.groundtruth.size(), file.pose.size());
  EXPECT_EQ(rec.anchors.size(), 8u);
  EXPECT_TRUE(im.report.warnings.empty()) << im.report.warnings.front().message;

  // IMU: SI units, gyro times, accelerometer interpolated onto them.
  const sim::LissajousWalk walk(flightParams());
  for (const ImuSample& s : rec.imu) {
    const sim::ImuReading truth = sim::idealImu(walk.at(static_cast<double>(s.t_ns) * 1e-9), spec.gravity);
    ASSERT_LT((s.gyro_rad_s - truth.gyro).norm(), 1e-9) << s.t_ns;
    ASSERT_LT((s.accel_m_s2 - truth.accel).norm(), 1e-4) << s.t_ns;
  }
  EXPECT_EQ(rec.imu.front().t_ns, 2'000'000);
  // TDoA: rilo's convention diff = |p - A_b| - |p - A_a| with a = idA, b = idB.
  for (const TdoaSample& s : rec.tdoa) {
    const double truth =
        truthTdoa(walk.at(static_cast<double>(s.t_ns) * 1e-9), importer::kUtilTagLeverArm, s.anchor_a, s.anchor_b);
    ASSERT_NEAR(s.diff_m, truth, 1e-9);
    ASSERT_EQ(s.anchor_b, (s.anchor_a + 1) % 8);
  }
  for (const GroundTruthPose& g : rec.groundtruth) {
    const Pose3 T = walk.at(static_cast<double>(g.t_ns) * 1e-9).T_w_b;
    ASSERT_LT((g.p_w_b - T.p).norm(), 1e-9);
    ASSERT_TRUE(sameRotation(g.q_w_b, Quat(T.R), 1e-12));
  }
  EXPECT_EQ(rec.meta.ranging, RangingKind::kTdoa);
  ASSERT_TRUE(rec.meta.imu_rate_hz.has_value());
  EXPECT_NEAR(*rec.meta.imu_rate_hz, 500.0, 1e-6);
  EXPECT_EQ(rec.meta.name, "const1-trial1-tdoa2");
  EXPECT_NE(rec.meta.description.find("const1-trial1-tdoa2.csv"), std::string::npos);
  EXPECT_NE(rec.meta.description.find("anchor_const1_survey.txt"), std::string::npos);
  EXPECT_TRUE(rec.meta.uwbLeverArm().isApprox(importer::kUtilTagLeverArm));
  EXPECT_DOUBLE_EQ(rec.meta.gravity_m_s2, 9.81);

  // Written with RecordingWriter, the folder reads back identically.
  importer::writeUtilRecording(im, dir / "rec", false);
  ReadReport report;
  const Recording back = readRecording(dir / "rec", &report);
  EXPECT_TRUE(report.warnings.empty());
  ASSERT_EQ(back.imu.size(), rec.imu.size());
  for (std::size_t i = 0; i < rec.imu.size(); ++i) {
    ASSERT_EQ(back.imu[i].t_ns, rec.imu[i].t_ns);
    ASSERT_EQ(back.imu[i].gyro_rad_s, rec.imu[i].gyro_rad_s);
    ASSERT_EQ(back.imu[i].accel_m_s2, rec.imu[i].accel_m_s2);
  }
  ASSERT_EQ(back.tdoa.size(), rec.tdoa.size());
  for (std::size_t i = 0; i < rec.tdoa.size(); ++i) {
    ASSERT_EQ(back.tdoa[i].t_ns, rec.tdoa[i].t_ns);
    ASSERT_EQ(back.tdoa[i].anchor_a, rec.tdoa[i].anchor_a);
    ASSERT_EQ(back.tdoa[i].anchor_b, rec.tdoa[i].anchor_b);
    ASSERT_EQ(back.tdoa[i].diff_m, rec.tdoa[i].diff_m);
  }
  ASSERT_EQ(back.groundtruth.size(), rec.groundtruth.size());
  for (std::size_t i = 0; i < rec.groundtruth.size(); ++i) {
    ASSERT_EQ(back.groundtruth[i].t_ns, rec.groundtruth[i].t_ns);
    ASSERT_EQ(back.groundtruth[i].p_w_b, rec.groundtruth[i].p_w_b);
    ASSERT_EQ(back.groundtruth[i].q_w_b.coeffs(), rec.groundtruth[i].q_w_b.coeffs());
  }
  ASSERT_EQ(back.anchors.size(), 8u);
  EXPECT_EQ(back.meta.ranging, RangingKind::kTdoa);
  EXPECT_EQ(back.meta.name, rec.meta.name);
  EXPECT_EQ(back.meta.description, rec.meta.description);
  EXPECT_EQ(back.meta.imu_rate_hz, rec.meta.imu_rate_hz);
  EXPECT_EQ(back.meta.uwb_lever_arm_m, rec.meta.uwb_lever_arm_m);
  // Refuses to overwrite without being asked.
  EXPECT_THROW(importer::writeUtilRecording(im, dir / "rec", false), std::exception);
  EXPECT_NO_THROW(importer::writeUtilRecording(im, dir / "rec", true));

  // The physics check agrees with every default option.
  const importer::PhysicsCheck check = importer::checkPhysics(rec);
  EXPECT_NEAR(check.accel.ratio_to_gravity, 1.0, 0.1);
  EXPECT_NEAR(check.gyro.scale, 1.0, 0.02);
  EXPECT_GT(check.gyro.windows, 20u);
  EXPECT_LT(check.tdoa.median_abs_residual_m, 1e-3);
  EXPECT_GT(check.tdoa.median_abs_residual_flipped_m, 0.3);
  const auto verdicts = importer::judgeUtilPhysics(check, im.options);
  for (const auto& v : verdicts) EXPECT_EQ(v.status, CheckStatus::kOk) << v.item << ": " << v.message;
  EXPECT_FALSE(importer::anyContradiction(verdicts));
  const std::string summary = importer::formatUtilSummary(im, check, verdicts);
  EXPECT_NE(summary.find("const1-trial1-tdoa2.csv"), std::string::npos);
  EXPECT_NE(summary.find("500.0 Hz"), std::string::npos);
  EXPECT_EQ(summary.find("CONTRADICTS"), std::string::npos);
}

TEST(UtilImport, AccelClockInterpolatesTheGyro) {
  UtilImportOptions options;
  options.imu_clock = importer::ImuClock::kAccel;
  const UtilImport im = parse(synthesize(SynthSpec{}), options);
  const sim::LissajousWalk walk(flightParams());
  // Every accelerometer sample but the last (after the last gyro sample) has partners.
  EXPECT_EQ(im.imu_without_partner, 1u);
  ASSERT_FALSE(im.recording.imu.empty());
  EXPECT_EQ(im.recording.imu.front().t_ns, 700'000);
  for (const ImuSample& s : im.recording.imu) {
    const sim::ImuReading truth = sim::idealImu(walk.at(static_cast<double>(s.t_ns) * 1e-9));
    ASSERT_LT((s.accel_m_s2 - truth.accel).norm(), 1e-9);
    ASSERT_LT((s.gyro_rad_s - truth.gyro).norm(), 1e-4);
  }
}

TEST(UtilImport, CheckDetectsAccelerometerUnit) {
  {  // File in g (as released), imported as m/s^2.
    UtilImportOptions options;
    options.accel_unit = AccelUnit::kMetersPerSecond2;
    const auto verdicts = judge(parse(synthesize(SynthSpec{}), options));
    const auto& v = verdict(verdicts, "accel unit");
    EXPECT_EQ(v.status, CheckStatus::kContradiction) << v.message;
    EXPECT_NE(v.message.find("use --accel-unit g"), std::string::npos) << v.message;
    EXPECT_TRUE(importer::anyContradiction(verdicts));
  }
  {  // File already in m/s^2, imported with the default g.
    SynthSpec spec;
    spec.accel_in_g = false;
    const auto verdicts = judge(parse(synthesize(spec)));
    const auto& v = verdict(verdicts, "accel unit");
    EXPECT_EQ(v.status, CheckStatus::kContradiction) << v.message;
    EXPECT_NE(v.message.find("use --accel-unit m/s2"), std::string::npos) << v.message;
    UtilImportOptions options;
    options.accel_unit = AccelUnit::kMetersPerSecond2;
    EXPECT_EQ(verdict(judge(parse(synthesize(spec), options)), "accel unit").status, CheckStatus::kOk);
  }
}

TEST(UtilImport, CheckDetectsGyroscopeUnit) {
  {  // File in deg/s, imported as rad/s: the gyro reads 57x too much.
    UtilImportOptions options;
    options.gyro_unit = GyroUnit::kRadPerSecond;
    const UtilImport im = parse(synthesize(SynthSpec{}), options);
    const importer::PhysicsCheck check = importer::checkPhysics(im.recording);
    EXPECT_NEAR(check.gyro.scale, std::numbers::pi / 180.0, 0.02 * std::numbers::pi / 180.0);
    const auto& v = verdict(importer::judgeUtilPhysics(check, options), "gyro unit");
    EXPECT_EQ(v.status, CheckStatus::kContradiction) << v.message;
    EXPECT_NE(v.message.find("use --gyro-unit deg/s"), std::string::npos) << v.message;
  }
  {  // File in rad/s, imported with the default deg/s.
    SynthSpec spec;
    spec.gyro_in_deg = false;
    const auto& v = verdict(judge(parse(synthesize(spec))), "gyro unit");
    EXPECT_EQ(v.status, CheckStatus::kContradiction) << v.message;
    EXPECT_NE(v.message.find("use --gyro-unit rad/s"), std::string::npos) << v.message;
  }
}

TEST(UtilImport, CheckDetectsFlippedTdoaSign) {
  SynthSpec spec;
  spec.tdoa_flipped = true;
  spec.tdoa_noise_m = 0.05;
  const UtilFile file = synthesize(spec);
  {
    const auto verdicts = judge(parse(file));
    const auto& v = verdict(verdicts, "tdoa sign");
    EXPECT_EQ(v.status, CheckStatus::kContradiction) << v.message;
    EXPECT_NE(v.message.find("use --tdoa-sign a-minus-b"), std::string::npos) << v.message;
    // No lever-arm or bias figures on top of a wrong sign.
    EXPECT_TRUE(std::none_of(verdicts.begin(), verdicts.end(),
                             [](const importer::CheckVerdict& x) { return x.item == "lever arm"; }));
  }
  UtilImportOptions options;
  options.tdoa_sign = TdoaSign::kAMinusB;
  const UtilImport im = parse(file, options);
  const auto verdicts = judge(im);
  EXPECT_EQ(verdict(verdicts, "tdoa sign").status, CheckStatus::kOk) << verdict(verdicts, "tdoa sign").message;
  // With the right option the stored diffs follow rilo's convention again.
  const sim::LissajousWalk walk(flightParams());
  double sum_sq = 0.0;
  for (const TdoaSample& s : im.recording.tdoa) {
    const double truth =
        truthTdoa(walk.at(static_cast<double>(s.t_ns) * 1e-9), importer::kUtilTagLeverArm, s.anchor_a, s.anchor_b);
    sum_sq += (s.diff_m - truth) * (s.diff_m - truth);
  }
  EXPECT_LT(std::sqrt(sum_sq / static_cast<double>(im.recording.tdoa.size())), 0.06);
}

TEST(UtilImport, CheckReportsLeverArmErrorAndPairBias) {
  SynthSpec spec;
  spec.true_lever_arm = importer::kUtilTagLeverArm + Vec3(0.06, -0.05, 0.08);
  spec.tdoa_noise_m = 0.03;
  spec.pair_bias_m[{2, 3}] = 0.15;
  const UtilImport im = parse(synthesize(spec));  // imported with the dataset's lever arm
  const importer::PhysicsCheck check = importer::checkPhysics(im.recording);
  ASSERT_TRUE(check.tdoa.fit_ok);
  EXPECT_TRUE(check.tdoa.lever_arm_evident);
  EXPECT_LT((check.tdoa.lever_arm_correction_m - Vec3(0.06, -0.05, 0.08)).norm(), 0.02)
      << check.tdoa.lever_arm_correction_m.transpose();
  ASSERT_FALSE(check.tdoa.pair_biases.empty());
  const importer::PairBias& largest = check.tdoa.pair_biases.front();
  EXPECT_EQ(largest.anchor_a, 2u);
  EXPECT_EQ(largest.anchor_b, 3u);
  EXPECT_NEAR(largest.bias_m, 0.15, 0.02);
  EXPECT_TRUE(largest.evident);
  for (std::size_t i = 1; i < check.tdoa.pair_biases.size(); ++i) {
    EXPECT_FALSE(check.tdoa.pair_biases[i].evident) << check.tdoa.pair_biases[i].bias_m;
  }
  const auto verdicts = importer::judgeUtilPhysics(check, im.options);
  EXPECT_EQ(verdict(verdicts, "lever arm").status, CheckStatus::kInconclusive);
  EXPECT_NE(verdict(verdicts, "tdoa bias").message.find("(2, 3) +0.1"), std::string::npos)
      << verdict(verdicts, "tdoa bias").message;
  EXPECT_EQ(verdict(verdicts, "tdoa sign").status, CheckStatus::kOk);
  EXPECT_FALSE(importer::anyContradiction(verdicts));

  // With the true lever arm as the option, nothing is evident about it.
  UtilImportOptions options;
  options.lever_arm_m = spec.true_lever_arm;
  const importer::PhysicsCheck right = importer::checkPhysics(parse(synthesize(spec), options).recording);
  ASSERT_TRUE(right.tdoa.fit_ok);
  EXPECT_FALSE(right.tdoa.lever_arm_evident) << right.tdoa.lever_arm_correction_m.transpose();
}

TEST(UtilImport, MissingColumnNamesFileLineAndColumn) {
  UtilFile f = synthesize(SynthSpec{});
  f.header.replace(f.header.find("acc_y"), 5, "acc_q");
  const std::string e = parseError(f);
  EXPECT_NE(e.find("const1-trial1-tdoa2.csv:1: column 'acc_y'"), std::string::npos) << e;
  EXPECT_NE(e.find("missing"), std::string::npos) << e;
}

TEST(UtilImport, BadFieldsNameFileLineAndColumn) {
  const UtilFile base = synthesize(SynthSpec{});
  const std::string prefix = "const1-trial1-tdoa2.csv:";
  {
    UtilFile f = base;
    f.tdoa[40][3] = "abc";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(40)) + ": column 'tdoa_meas'"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.gyro[123][1] = "nan";  // what Python's csv writes for a NaN
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(123)) + ": column 'gyro_x'"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.pose[7][2] = "inf";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(7)) + ": column 'pose_y'"), std::string::npos) << e;
  }
  {  // A sample block filled only partly.
    UtilFile f = base;
    f.acc[55][3] = "";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(55)) + ": column 'acc_z'"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.tdoa[3][1] = "9.0";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(3)) + ": column 'idA'"), std::string::npos) << e;
    EXPECT_NE(e.find("not in anchor_const1_survey.txt"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.tdoa[3][2] = "1.5";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(3)) + ": column 'idB'"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.tdoa[3][2] = f.tdoa[3][1];
    const std::string e = parseError(f);
    EXPECT_NE(e.find("idB equals idA"), std::string::npos) << e;
  }
  {
    UtilFile f = base;
    f.pose[9][7] = "0.5";  // qw: the norm is far from 1
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(9)) + ": column 'pose_qx'"), std::string::npos) << e;
  }
  {  // A row with a field too many.
    UtilFile f = base;
    f.baro[2][1] += ",1";
    const std::string e = parseError(f);
    EXPECT_NE(e.find(prefix + std::to_string(lineOf(2)) + ":"), std::string::npos) << e;
  }
  EXPECT_EQ(parseError(base), "");
}

TEST(UtilImport, OutOfOrderTimeFailsOrIsDroppedAndCounted) {
  UtilFile f = synthesize(SynthSpec{});
  std::swap(f.acc[100], f.acc[101]);
  const std::string e = parseError(f);
  EXPECT_NE(e.find("const1-trial1-tdoa2.csv:" + std::to_string(lineOf(101)) + ": column 't_acc'"), std::string::npos)
      << e;
  EXPECT_NE(e.find("earlier than"), std::string::npos) << e;

  UtilImportOptions options;
  options.drop_unordered = true;
  const UtilImport im = parse(f, options);
  EXPECT_EQ(im.accel.rows, f.acc.size());
  EXPECT_EQ(im.accel.unordered, 1u);
  EXPECT_EQ(im.accel.kept, f.acc.size() - 1);
  EXPECT_EQ(im.accel.first_unordered_line, lineOf(101));
  const std::string summary =
      importer::formatUtilSummary(im, importer::checkPhysics(im.recording), judge(im));
  EXPECT_NE(summary.find("first unordered: line " + std::to_string(lineOf(101))), std::string::npos) << summary;
}

TEST(UtilImport, DuplicatesAreDroppedAndCounted) {
  UtilFile f = synthesize(SynthSpec{});
  f.gyro.insert(f.gyro.begin() + 30, f.gyro[29]);   // logged twice
  f.tdoa.insert(f.tdoa.begin() + 12, f.tdoa[11]);
  const UtilImport im = parse(f);
  EXPECT_EQ(im.gyro.duplicates, 1u);
  EXPECT_EQ(im.gyro.first_duplicate_line, lineOf(30));
  EXPECT_EQ(im.gyro.kept, f.gyro.size() - 1);
  EXPECT_EQ(im.tdoa.duplicates, 1u);
  EXPECT_EQ(im.recording.tdoa.size(), f.tdoa.size() - 1);

  // Same time and pair, another value: an error, not a duplicate.
  UtilFile conflict = synthesize(SynthSpec{});
  conflict.tdoa.insert(conflict.tdoa.begin() + 12, conflict.tdoa[11]);
  conflict.tdoa[12][3] = "0.123";
  const std::string e = parseError(conflict);
  EXPECT_NE(e.find(":" + std::to_string(lineOf(12)) + ": column 't_tdoa'"), std::string::npos) << e;
  // Same time, another pair: TDoA3 may report several pairs at once.
  UtilFile other_pair = synthesize(SynthSpec{});
  other_pair.tdoa.insert(other_pair.tdoa.begin() + 12, other_pair.tdoa[11]);
  other_pair.tdoa[12][1] = "5.0";
  other_pair.tdoa[12][2] = "6.0";
  EXPECT_EQ(parseError(other_pair), "");
  // Same gyro time, other values: an error.
  UtilFile gyro_conflict = synthesize(SynthSpec{});
  gyro_conflict.gyro.insert(gyro_conflict.gyro.begin() + 30, gyro_conflict.gyro[29]);
  gyro_conflict.gyro[30][2] = "1.5";
  EXPECT_NE(parseError(gyro_conflict).find(":" + std::to_string(lineOf(30)) + ": column 't_gyro'"), std::string::npos);
}

TEST(UtilImport, EmptyOrHeaderOnlyFlightIsAnError) {
  const importer::UtilSurvey survey = importer::parseUtilSurvey(surveyText(), "s.txt");
  EXPECT_THROW(importer::parseUtilFlight("", "f.csv", survey, {}), RecordingError);
  try {
    importer::parseUtilFlight(std::string(kHeader) + "\n", "f.csv", survey, {});
    FAIL() << "no error";
  } catch (const RecordingError& e) {
    EXPECT_NE(std::string(e.what()).find("no TDoA sample"), std::string::npos) << e.what();
  }
  testing::ScratchDir dir("util_import");
  EXPECT_THROW(importer::importUtil(dir / "missing.csv", dir / "missing.txt", {}), RecordingError);
}

TEST(UtilImport, OptionSpellings) {
  EXPECT_EQ(importer::accelUnitFromString("g"), AccelUnit::kG);
  EXPECT_EQ(importer::accelUnitFromString("m/s^2"), AccelUnit::kMetersPerSecond2);
  EXPECT_EQ(importer::accelUnitFromString("m/s2"), AccelUnit::kMetersPerSecond2);
  EXPECT_FALSE(importer::accelUnitFromString("G").has_value());
  EXPECT_EQ(importer::gyroUnitFromString("rad/s"), GyroUnit::kRadPerSecond);
  EXPECT_EQ(importer::tdoaSignFromString("a-minus-b"), TdoaSign::kAMinusB);
  EXPECT_EQ(importer::imuClockFromString("accel"), importer::ImuClock::kAccel);
  for (const AccelUnit u : {AccelUnit::kG, AccelUnit::kMetersPerSecond2}) {
    EXPECT_EQ(importer::accelUnitFromString(importer::toString(u)), u);
  }
  for (const TdoaSign s : {TdoaSign::kBMinusA, TdoaSign::kAMinusB}) {
    EXPECT_EQ(importer::tdoaSignFromString(importer::toString(s)), s);
  }
  UtilImportOptions bad;
  bad.gravity_m_s2 = -1.0;
  EXPECT_THROW(parse(synthesize(SynthSpec{}), bad), std::invalid_argument);
}

}  // namespace
}  // namespace rilo
