// Range errors against the ground truth (evaluation/range_errors.h) on
// recordings built here with known errors, and `rilo range-errors` on the
// committed office demo and on a recording without ground truth.
#include "evaluation/range_errors.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "eval_test_support.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

constexpr std::int64_t kMs = 1'000'000;

/// 20 s of a walk at 100 Hz ground truth: along a circle of 5 m radius about
/// (5, 5, 1.5) at 0.2 rad/s, the body turning with it (yaw = heading), so the
/// distance to each anchor changes at varying speed and sign; two anchors,
/// two antennas (tag 0 at the meta lever arm, tag 1 from tags.csv).
Recording circleWalk() {
  Recording rec;
  rec.meta.uwb_lever_arm_m = Vec3(0.10, 0.0, 0.20);
  rec.tags = {Tag{0, Vec3(0.10, 0.0, 0.20)}, Tag{1, Vec3(-0.05, 0.15, 0.30)}};
  rec.anchors = {Anchor{0, Vec3(0.0, 0.0, 2.5), AnchorKind::kUwb, std::nullopt},
                 Anchor{3, Vec3(12.0, 9.0, 0.8), AnchorKind::kUwb, std::nullopt}};
  for (std::int64_t t = 0; t <= 20'000 * kMs; t += 10 * kMs) {
    const double s = static_cast<double>(t) * 1e-9;
    const double a = 0.2 * s;
    GroundTruthPose g;
    g.t_ns = t;
    g.p_w_b = Vec3(5.0 + 5.0 * std::cos(a), 5.0 + 5.0 * std::sin(a), 1.5);
    g.q_w_b = Quat(Eigen::AngleAxisd(a + M_PI / 2, Vec3::UnitZ()));
    rec.groundtruth.push_back(g);
  }
  return rec;
}

/// The true distance from `anchor` to antenna `tag` at `t_ns` (exact, from the circle).
double trueDistance(const Recording& rec, std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns) {
  const double a = 0.2 * static_cast<double>(t_ns) * 1e-9;
  const Vec3 p(5.0 + 5.0 * std::cos(a), 5.0 + 5.0 * std::sin(a), 1.5);
  const Mat3 R = Eigen::AngleAxisd(a + M_PI / 2, Vec3::UnitZ()).toRotationMatrix();
  return (p + R * *rec.findTagLeverArm(tag) - rec.findAnchor(anchor)->p_w_anchor).norm();
}

TEST(RangeErrors, AnErrorIsTheRangeMinusTheDistanceFromTheAnchorToTheAntennaThatMeasured) {
  Recording rec = circleWalk();
  std::vector<double> added;
  for (int i = 0; i < 150; ++i) {
    RangeSample r;
    r.t_ns = 1'000 * kMs + i * 120 * kMs + (i % 7) * kMs;  // between ground-truth samples too
    r.anchor_id = i % 2 == 0 ? 0 : 3;
    r.tag_id = static_cast<std::uint32_t>(i % 3 == 0 ? 1 : 0);
    r.los = i % 4 == 0 ? 0 : 1;
    added.push_back(0.01 * (i % 50) - 0.2);
    r.range_m = trueDistance(rec, r.anchor_id, r.tag_id, r.t_ns) + added.back();
    rec.ranges.push_back(r);
  }
  const RangeErrors out = rangeErrors(rec);
  ASSERT_EQ(out.errors.size(), rec.ranges.size());
  EXPECT_EQ(out.without_truth + out.unknown_anchor + out.unknown_tag, 0u);
  for (std::size_t i = 0; i < out.errors.size(); ++i) {
    const RangeError& e = out.errors[i];
    // Interpolation between 10 ms samples of a 1 m/s circle: sub-millimetre.
    EXPECT_NEAR(e.error_m, added[i], 2e-4) << "range " << i;
    EXPECT_NEAR(e.true_m, trueDistance(rec, e.anchor_id, e.tag_id, e.t_ns), 2e-4) << "range " << i;
    EXPECT_EQ(e.range_m, rec.ranges[i].range_m);
    EXPECT_EQ(e.anchor_id, rec.ranges[i].anchor_id);
    EXPECT_EQ(e.tag_id, rec.ranges[i].tag_id);
    EXPECT_EQ(e.los, rec.ranges[i].los);
    // The radial speed is the true distance's rate of change.
    const double h = 1e-3;
    const double rate = (trueDistance(rec, e.anchor_id, e.tag_id, e.t_ns + static_cast<std::int64_t>(h * 1e9)) -
                         trueDistance(rec, e.anchor_id, e.tag_id, e.t_ns - static_cast<std::int64_t>(h * 1e9))) /
                        (2 * h);
    EXPECT_NEAR(e.radial_speed_m_s, rate, 5e-3) << "range " << i;
  }
}

TEST(RangeErrors, ARangeStampedLateErrsByMinusTheDelayTimesTheRadialSpeed) {
  Recording rec = circleWalk();
  const std::int64_t delay_ns = 400 * kMs;
  for (int i = 0; i < 300; ++i) {
    RangeSample r;
    r.t_ns = 1'000 * kMs + i * 60 * kMs;
    r.anchor_id = i % 2 == 0 ? 0 : 3;
    r.range_m = trueDistance(rec, r.anchor_id, 0, r.t_ns - delay_ns);  // measured 0.4 s before its stamp
    rec.ranges.push_back(r);
  }
  const RangeErrorStats s = summarizeRangeErrors(rangeErrors(rec).errors);
  EXPECT_NEAR(s.radial_slope_s, -0.4, 0.02);
  EXPECT_LT(s.radial_correlation, -0.99);
  // The truth taken 0.4 s before each stamp: the errors vanish.
  RangeErrorOptions shifted;
  shifted.truth_shift_s = 0.4;
  const RangeErrors at_shift = rangeErrors(rec, shifted);
  ASSERT_EQ(at_shift.errors.size(), rec.ranges.size());
  for (const RangeError& e : at_shift.errors) EXPECT_NEAR(e.error_m, 0.0, 2e-4);
  EXPECT_LT(std::abs(summarizeRangeErrors(at_shift.errors).mean_m), 1e-4);
}

TEST(RangeErrors, RangesWithoutTruthAnchorOrTagAreCountedNotGuessed) {
  Recording rec = circleWalk();
  auto range = [](std::int64_t t_ns, std::uint32_t anchor, std::uint32_t tag) {
    RangeSample r;
    r.t_ns = t_ns;
    r.anchor_id = anchor;
    r.tag_id = tag;
    r.range_m = 5.0;
    return r;
  };
  rec.ranges = {range(3'000 * kMs, 0, 0), range(25'000 * kMs, 0, 0), range(6'000 * kMs, 9, 0),
                range(7'000 * kMs, 3, 4)};
  // A hole in the ground truth is not bridged.
  rec.groundtruth.erase(rec.groundtruth.begin() + 500, rec.groundtruth.begin() + 600);  // 5-6 s
  rec.ranges.push_back(range(5'500 * kMs, 0, 0));
  RangeSample not_finite = range(8'000 * kMs, 0, 0);
  not_finite.range_m = std::nan("");
  rec.ranges.push_back(not_finite);
  const RangeErrors out = rangeErrors(rec);
  EXPECT_EQ(out.errors.size(), 1u);
  EXPECT_EQ(out.without_truth, 2u);
  EXPECT_EQ(out.unknown_anchor, 1u);
  EXPECT_EQ(out.unknown_tag, 1u);
  EXPECT_EQ(out.non_finite, 1u);
  // At the edges of the ground truth (on its first and last sample, and
  // just inside) a range has its error but no radial speed.
  Recording edge = circleWalk();
  edge.ranges = {range(0, 0, 0), range(kMs, 3, 0), range(20'000 * kMs - kMs, 0, 0), range(20'000 * kMs, 3, 1)};
  const RangeErrors at_edge = rangeErrors(edge);
  ASSERT_EQ(at_edge.errors.size(), 4u);
  for (const RangeError& e : at_edge.errors) {
    EXPECT_NEAR(e.true_m, trueDistance(edge, e.anchor_id, e.tag_id, e.t_ns), 2e-4) << e.t_ns;
    EXPECT_TRUE(std::isnan(e.radial_speed_m_s)) << e.t_ns;
  }
}

TEST(RangeErrors, StatsHaveTheQuantilesAndSharesOfTheErrors) {
  std::vector<RangeError> errors;
  for (int i = 0; i <= 100; ++i) {
    RangeError e;
    e.error_m = -0.5 + 0.01 * i;  // -0.50 .. +0.50
    errors.push_back(e);
  }
  const RangeErrorStats s = summarizeRangeErrors(errors, 0.305);  // off the grid: no value on the boundary
  EXPECT_EQ(s.count, 101u);
  EXPECT_NEAR(s.mean_m, 0.0, 1e-12);
  EXPECT_NEAR(s.median_m, 0.0, 1e-12);
  EXPECT_NEAR(s.p1_m, -0.49, 1e-12);
  EXPECT_NEAR(s.p5_m, -0.45, 1e-12);
  EXPECT_NEAR(s.p95_m, 0.45, 1e-12);
  EXPECT_NEAR(s.p99_m, 0.49, 1e-12);
  EXPECT_NEAR(s.short_share, 20.0 / 101.0, 1e-12);  // -0.50 .. -0.31
  EXPECT_NEAR(s.long_share, 20.0 / 101.0, 1e-12);
  EXPECT_TRUE(std::isnan(s.radial_slope_s)) << "no radial speeds";
  // Between order statistics: 4 values, the median halfway between the middle two.
  const std::vector<RangeError> four(errors.begin(), errors.begin() + 4);
  EXPECT_NEAR(summarizeRangeErrors(four).median_m, -0.485, 1e-12);

  const RangeErrorStats none = summarizeRangeErrors({});
  EXPECT_EQ(none.count, 0u);
  EXPECT_TRUE(std::isnan(none.median_m));
  EXPECT_TRUE(std::isnan(none.short_share));
  EXPECT_THROW(summarizeRangeErrors(errors, -0.1), std::invalid_argument);
}

TEST(RangeErrors, ARecordingWithoutGroundTruthOrWithBadOptionsIsRefused) {
  Recording rec = circleWalk();
  RangeErrorOptions bad;
  bad.radial_step_s = 0.0;
  EXPECT_THROW(rangeErrors(rec, bad), std::invalid_argument);
  bad = {};
  bad.truth_shift_s = std::numeric_limits<double>::infinity();
  EXPECT_THROW(rangeErrors(rec, bad), std::invalid_argument);
  bad = {};
  bad.max_truth_gap_s = std::nan("");
  EXPECT_THROW(rangeErrors(rec, bad), std::invalid_argument);
  rec.groundtruth.clear();
  try {
    rangeErrors(rec);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("groundtruth.csv"), std::string::npos) << e.what();
  }
}

TEST(RiloRangeErrors, PrintsTheTablePerLabelAndAnchorAndWritesEveryRange) {
  testing::TempDir dir("rilo-range-errors");
  const std::string demo = testing::officeDemoDir().string();
  const std::string csv = (dir / "errors.csv").string();
  const testing::ToolRun run = testing::runRilo({"range-errors", demo, "--csv", csv}, dir.path());
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const Recording rec = readRecording(demo);
  EXPECT_NE(run.out.find("## " + demo), std::string::npos) << run.out;
  EXPECT_NE(run.out.find(std::to_string(rec.ranges.size()) + " ranges with ground truth"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("| all | " + std::to_string(rec.ranges.size()) + " |"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("| labelled LOS |"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("| labelled NLOS |"), std::string::npos) << run.out;
  for (const Anchor& a : rec.anchors) {
    EXPECT_NE(run.out.find("| anchor " + std::to_string(a.id) + " |"), std::string::npos) << a.id;
  }
  const std::string text = testing::readFile(csv);
  std::size_t lines = 0;
  for (char c : text) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, rec.ranges.size() + 1);
  EXPECT_EQ(text.rfind("recording,t_ns,anchor_id,tag_id,range_m,true_m,error_m,radial_speed_m_s,los\n", 0), 0u);
}

TEST(RiloRangeErrors, APathWithACommaIsQuotedInTheCsv) {
  testing::TempDir dir("rilo-range-errors-comma");
  const std::filesystem::path rec = dir / "office,demo";
  std::filesystem::create_directory_symlink(testing::officeDemoDir(), rec);
  const std::string csv = (dir / "errors.csv").string();
  const testing::ToolRun run = testing::runRilo({"range-errors", rec.string(), "--csv", csv}, dir.path());
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const std::string text = testing::readFile(csv);
  const std::size_t second_line = text.find('\n') + 1;
  EXPECT_EQ(text.compare(second_line, rec.string().size() + 3, "\"" + rec.string() + "\","), 0)
      << text.substr(0, 300);
}

TEST(RiloRangeErrors, ARecordingWithoutGroundTruthIsBadInputNamingIt) {
  testing::TempDir dir("rilo-range-errors-bad");
  const std::filesystem::path rec = dir / "no-truth";
  std::filesystem::create_directories(rec);
  for (const char* file : {"meta.yaml", "anchors.csv", "imu.csv", "range.csv"}) {
    std::filesystem::copy_file(testing::officeDemoDir() / file, rec / file);
  }
  // After a good one: the CSV asked for is not left half-written.
  const std::string csv = (dir / "errors.csv").string();
  const testing::ToolRun run = testing::runRilo(
      {"range-errors", testing::officeDemoDir().string(), rec.string(), "--csv", csv}, dir.path());
  EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
  EXPECT_NE(run.err.find(rec.string()), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("groundtruth.csv"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(csv));
}

}  // namespace
}  // namespace rilo
