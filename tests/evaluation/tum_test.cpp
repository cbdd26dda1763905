// TUM trajectory reader and writer: exact round trip, the format the tools
// write, and an error naming file, line and field for every malformed line.
#include "evaluation/tum.h"

#include <gtest/gtest.h>

#include <ostream>
#include <string>

#include "eval_test_support.h"
#include "math/so3.h"

namespace rilo {
namespace {

double rotationAngle(const Mat3& R_a, const Mat3& R_b) { return so3::log(R_a.transpose() * R_b).norm(); }

TumTrajectory samplePoses() {
  TumTrajectory poses;
  const std::int64_t times_ns[] = {-1'500'000'001, 0, 1, 999'999'999, 1'000'000'000, 45'123'456'789,
                                   1'700'000'000'123'456'789};
  int k = 0;
  for (std::int64_t t_ns : times_ns) {
    const Vec3 phi(0.3 * k - 1.0, 0.2 + 0.1 * k, -0.7 * k);
    const Vec3 p(12.345678 * k - 3.0, -0.000001 * k, 1e4 + k);
    poses.push_back({t_ns, Pose3(so3::exp(phi), p)});
    ++k;
  }
  return poses;
}

TEST(Tum, RoundTripKeepsTimesExactly) {
  const TumTrajectory poses = samplePoses();
  const TumTrajectory back = parseTum(formatTum(poses), "mem.tum");
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(back[k].t_ns, poses[k].t_ns) << k;
    EXPECT_LE((back[k].T_w_b.p - poses[k].T_w_b.p).cwiseAbs().maxCoeff(), 5.0000001e-7) << k;
    EXPECT_LT(rotationAngle(back[k].T_w_b.R, poses[k].T_w_b.R), 1e-8) << k;
  }
}

TEST(Tum, FileRoundTrip) {
  testing::TempDir dir("tum");
  const TumTrajectory poses = samplePoses();
  writeTum(dir / "traj.tum", poses);
  const TumTrajectory back = readTum(dir / "traj.tum");
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(back[k].t_ns, poses[k].t_ns);
    EXPECT_LE((back[k].T_w_b.p - poses[k].T_w_b.p).cwiseAbs().maxCoeff(), 5.0000001e-7) << k;
    EXPECT_LT(rotationAngle(back[k].T_w_b.R, poses[k].T_w_b.R), 1e-8) << k;
  }
  // Rewritten, the text keeps its times and positions (quaternions may differ
  // in the last digit: the rotation is re-normalised in between).
  writeTum(dir / "again.tum", back);
  const TumTrajectory again = readTum(dir / "again.tum");
  ASSERT_EQ(again.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(again[k].t_ns, poses[k].t_ns);
    EXPECT_EQ(again[k].T_w_b.p, back[k].T_w_b.p);
  }
}

TEST(Tum, WritesTheToolsFormat) {
  TumTrajectory poses = {{1'000'000'000, Pose3(Mat3::Identity(), Vec3(1.0, 2.0, -3.25))},
                         {-5, Pose3(Quat(0.0, 0.0, 0.0, 1.0), Vec3::Zero())}};
  EXPECT_EQ(formatTum(poses),
            "# t_s x y z qx qy qz qw (TUM; world frame of the anchors)\n"
            "1.000000000 1.000000 2.000000 -3.250000 0.000000000 0.000000000 0.000000000 1.000000000\n"
            "-0.000000005 0.000000 0.000000 0.000000 0.000000000 0.000000000 1.000000000 0.000000000\n");
}

TEST(Tum, AcceptsCommentsBlankLinesTabsAndCrlf) {
  const std::string text =
      "# header\n"
      "\n"
      "   \t \n"
      "1.0 1 2 3 0 0 0 1   # inline comment\r\n"
      "\t2.5\t4\t5\t6\t0\t0\t0.7071067811865476\t0.7071067811865476\n"
      "   # indented comment\n"
      "3 1e-3 -2.5E1 0 0 0 0 1.0004";  // no final newline; |q| within 1e-3 of 1
  const TumTrajectory poses = parseTum(text, "ok.tum");
  ASSERT_EQ(poses.size(), 3u);
  EXPECT_EQ(poses[0].t_ns, 1'000'000'000);
  EXPECT_EQ(poses[1].t_ns, 2'500'000'000);
  EXPECT_EQ(poses[2].t_ns, 3'000'000'000);
  EXPECT_TRUE(poses[0].T_w_b.p.isApprox(Vec3(1, 2, 3)));
  EXPECT_NEAR(rotationAngle(Mat3::Identity(), poses[1].T_w_b.R), 3.14159265358979 / 2, 1e-12);
  EXPECT_NEAR((poses[1].T_w_b.R * Vec3::UnitX() - Vec3::UnitY()).norm(), 0.0, 1e-12);  // x,y,z,w order
  EXPECT_NEAR(poses[2].T_w_b.p.y(), -25.0, 1e-12);
  EXPECT_NEAR((poses[2].T_w_b.R - Mat3::Identity()).norm(), 0.0, 1e-12);  // normalised
}

TEST(Tum, TimesAreConvertedExactly) {
  const auto t = [](const std::string& field) {
    return parseTum(field + " 0 0 0 0 0 0 1\n", "t.tum").at(0).t_ns;
  };
  EXPECT_EQ(t("1700000000.123456789"), 1'700'000'000'123'456'789);
  EXPECT_EQ(t("0.0000000015"), 2);
  EXPECT_EQ(t("0.0000000014999"), 1);
  EXPECT_EQ(t("-0.5"), -500'000'000);
  EXPECT_EQ(t(".25"), 250'000'000);
  EXPECT_EQ(t("7."), 7'000'000'000);
  EXPECT_EQ(t("1.5e-3"), 1'500'000);
  EXPECT_EQ(t("9223372036.854775807"), 9'223'372'036'854'775'807);
}

struct Malformed {
  const char* name;
  std::string text;
  std::size_t line;
  std::size_t field;  // 0: the line as a whole
  const char* detail;
};

// Test names show the case, not a byte dump.
void PrintTo(const Malformed& m, std::ostream* os) { *os << m.name; }

class TumMalformed : public ::testing::TestWithParam<Malformed> {};

TEST_P(TumMalformed, IsAnErrorNamingFileLineAndField) {
  const Malformed& m = GetParam();
  try {
    parseTum(m.text, "bad.tum");
    FAIL() << "accepted: " << m.text;
  } catch (const TumError& e) {
    const std::string what = e.what();
    EXPECT_EQ(e.file(), "bad.tum");
    EXPECT_EQ(e.line(), m.line) << what;
    EXPECT_EQ(e.field(), m.field) << what;
    const std::string where = "bad.tum:" + std::to_string(m.line) + ": ";
    EXPECT_EQ(what.rfind(where, 0), 0u) << what;
    if (m.field > 0) {
      const std::string field = "field " + std::to_string(m.field) + " (" + std::string(tumFieldName(m.field)) + ")";
      EXPECT_NE(what.find(field), std::string::npos) << what;
    }
    EXPECT_NE(what.find(m.detail), std::string::npos) << what;
  }
}

const std::string kGood = "1 0 0 0 0 0 0 1\n";

INSTANTIATE_TEST_SUITE_P(
    EveryCase, TumMalformed,
    ::testing::Values(
        Malformed{"SevenFields", kGood + "2 0 0 0 0 0 1\n", 2, 0, "expected 8 fields (t x y z qx qy qz qw), found 7"},
        Malformed{"NineFields", "# c\n" + kGood + "2 0 0 0 0 0 0 1 5\n", 3, 0, "found 9"},
        Malformed{"CommaSeparated", "1,0,0,0,0,0,0,1\n", 1, 0, "found 1"},
        Malformed{"NotANumberY", kGood + "\n2 0 abc 0 0 0 0 1\n", 3, 3, "'abc' is not a number"},
        Malformed{"TrailingGarbage", kGood + "2 0 0 1.5m 0 0 0 1\n", 2, 4, "'1.5m' is not a number"},
        Malformed{"LeadingPlus", "+1 0 0 0 0 0 0 1\n", 1, 1, "'+1' is not a number"},
        Malformed{"NanQx", kGood + "2 0 0 0 nan 0 0 1\n", 2, 5, "'nan' is not finite"},
        Malformed{"InfTime", "inf 0 0 0 0 0 0 1\n", 1, 1, "'inf' is not finite"},
        Malformed{"HugeX", "1 1e999 0 0 0 0 0 1\n", 1, 2, "out of range"},
        Malformed{"TimeBeyondInt64", "1e20 0 0 0 0 0 0 1\n", 1, 1, "out of range for int64 nanoseconds"},
        Malformed{"TimeBeyondInt64Decimal", "9223372037 0 0 0 0 0 0 1\n", 1, 1, "out of range"},
        Malformed{"RepeatedTime", kGood + "1.000000000 0 0 0 0 0 0 1\n", 2, 1,
                  "time 1.000000000 s is not after the previous pose's 1.000000000 s (line 1)"},
        Malformed{"DecreasingTime", kGood + "# gap\n3 0 0 0 0 0 0 1\n2.5 0 0 0 0 0 0 1\n", 4, 1,
                  "is not after the previous pose's 3.000000000 s (line 3)"},
        Malformed{"QuaternionTooLong", kGood + "2 0 0 0 0 0 0 1.002\n", 2, 5, "differs from 1 by more than 0.001"},
        Malformed{"QuaternionZero", "1 0 0 0 0 0 0 0\n", 1, 5, "norm 0"},
        Malformed{"WxyzOrderHalfNorm", "1 0 0 0 0.5 0 0 0.5\n", 1, 5, "norm 0.707107"}),
    [](const ::testing::TestParamInfo<Malformed>& param_info) { return std::string(param_info.param.name); });

TEST(Tum, MissingFileIsAnErrorNamingIt) {
  try {
    readTum("/nonexistent/est.tum");
    FAIL();
  } catch (const TumError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/est.tum"), std::string::npos) << e.what();
    EXPECT_EQ(e.line(), 0u);
  }
  testing::TempDir dir("tum");
  EXPECT_THROW(readTum(dir.path()), TumError);  // a folder
}

TEST(Tum, ReadFileErrorsNameThePath) {
  testing::TempDir dir("tum");
  testing::writeFile(dir / "est.tum", "1 0 0 0 0 0 0 1\n2 0 x 0 0 0 0 1\n");
  try {
    readTum(dir / "est.tum");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "est.tum").string() + ":2: field 3 (y)"), std::string::npos)
        << e.what();
  }
}

TEST(Tum, EmptyFileHasNoPoses) {
  EXPECT_TRUE(parseTum("", "e.tum").empty());
  EXPECT_TRUE(parseTum("# only a header\n\n", "e.tum").empty());
}

}  // namespace
}  // namespace rilo
