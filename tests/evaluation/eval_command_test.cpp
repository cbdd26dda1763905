// `rilo eval` as a subprocess on the committed recording tests/data/office-demo:
// an estimate written from the recording's own ground truth plus a known
// offset has APE = the offset and no relative error; bad input exits with 1
// and a message naming the problem.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "eval_test_support.h"
#include "evaluation/tum.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

using testing::jsonNumberAt;

const Vec3 kOffset(0.3, -0.4, 1.2);  // horizontal 0.5 m, vertical 1.2 m, 3D 1.3 m

TumTrajectory offsetTruth(const Recording& rec) {
  TumTrajectory est;
  for (const GroundTruthPose& g : rec.groundtruth) {
    const Pose3 T = g.pose();
    est.push_back({g.t_ns, Pose3(T.R, T.p + kOffset)});
  }
  return est;
}

class RiloEval : public ::testing::Test {
 protected:
  void SetUp() override {
    rec_ = readRecording(testing::officeDemoDir());
    ASSERT_GT(rec_.groundtruth.size(), 1000u);
  }
  testing::ToolRun eval(const std::vector<std::string>& args) { return testing::runRilo(args, dir_.path()); }

  Recording rec_;
  testing::TempDir dir_{"rilo-eval"};
  const std::string rec_dir_ = testing::officeDemoDir().string();
};

TEST_F(RiloEval, OffsetGroundTruthGivesTheOffset) {
  const std::string est = (dir_ / "est.tum").string();
  const std::string json_file = (dir_ / "eval.json").string();
  writeTum(est, offsetTruth(rec_));
  const testing::ToolRun run = eval({"eval", est, rec_dir_, "--json", json_file});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("APE 3D (m)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("RPE 1 s trans (m)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("RPE 10 m rot (deg)"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find(" 0 without"), std::string::npos) << run.out;

  const std::string json = testing::readFile(json_file);
  ASSERT_FALSE(json.empty());
  const double n = static_cast<double>(rec_.groundtruth.size());
  EXPECT_EQ(jsonNumberAt(json, {"poses", "estimated"}), n);
  EXPECT_EQ(jsonNumberAt(json, {"poses", "matched"}), n);
  EXPECT_EQ(jsonNumberAt(json, {"poses", "unmatched"}), 0.0);
  EXPECT_EQ(jsonNumberAt(json, {"max_dt_ms"}), 50.0);
  for (const char* stat : {"mean", "median", "rmse", "max"}) {
    // Positions are written with 6 decimals.
    EXPECT_NEAR(jsonNumberAt(json, {"ape_m", "3d", stat}), 1.3, 2e-6) << stat;
    EXPECT_NEAR(jsonNumberAt(json, {"ape_m", "horizontal", stat}), 0.5, 2e-6) << stat;
    EXPECT_NEAR(jsonNumberAt(json, {"ape_m", "vertical", stat}), 1.2, 2e-6) << stat;
  }
  EXPECT_EQ(jsonNumberAt(json, {"ape_m", "3d", "count"}), n);
  // Quaternions read in the right (x,y,z,w) order: no relative rotation error.
  EXPECT_EQ(jsonNumberAt(json, {"rpe_time", "delta_s"}), 1.0);
  EXPECT_GT(jsonNumberAt(json, {"rpe_time", "pairs"}), 2000.0);
  EXPECT_LT(jsonNumberAt(json, {"rpe_time", "translation_m", "max"}), 2e-6);
  EXPECT_LT(jsonNumberAt(json, {"rpe_time", "rotation_deg", "max"}), 1e-4);
  EXPECT_EQ(jsonNumberAt(json, {"rpe_distance", "delta_m"}), 10.0);
  EXPECT_GT(jsonNumberAt(json, {"rpe_distance", "pairs"}), 100.0);  // the walk is ~26 m long
  EXPECT_LT(jsonNumberAt(json, {"rpe_distance", "translation_m", "max"}), 2e-6);
  EXPECT_LT(jsonNumberAt(json, {"rpe_distance", "rotation_deg", "max"}), 1e-4);
}

TEST_F(RiloEval, ShiftedTimesWithinToleranceStillMatch) {
  // 7 ms late (ground truth every 20 ms): every pose is 7 ms from its partner.
  TumTrajectory est = offsetTruth(rec_);
  for (auto& p : est) p.t_ns += 7'000'000;
  const std::string file = (dir_ / "late.tum").string();
  writeTum(file, est);
  const std::string json_file = (dir_ / "e.json").string();
  const testing::ToolRun ok = eval({"eval", file, rec_dir_, "--json", json_file});
  ASSERT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  const std::string json = testing::readFile(json_file);
  EXPECT_EQ(jsonNumberAt(json, {"poses", "matched"}), static_cast<double>(rec_.groundtruth.size()));
  EXPECT_NEAR(jsonNumberAt(json, {"poses", "max_abs_dt_ms"}), 7.0, 1e-9);
  const testing::ToolRun run = eval({"eval", file, rec_dir_, "--max-dt-ms", "5"});
  // Within 5 ms nothing matches: that is an error saying why.
  EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
  EXPECT_NE(run.err.find("no estimated pose has ground truth within 5 ms"), std::string::npos) << run.err;
}

TEST_F(RiloEval, PosesWithoutGroundTruthAreCountedAndReported) {
  TumTrajectory est = offsetTruth(rec_);
  const std::int64_t end_ns = rec_.groundtruth.back().t_ns;
  for (std::int64_t k = 1; k <= 3; ++k) est.push_back({end_ns + k * 1'000'000'000, Pose3(Mat3::Identity(), Vec3(99, 99, 99))});
  const std::string file = (dir_ / "est.tum").string();
  const std::string json_file = (dir_ / "eval.json").string();
  writeTum(file, est);
  const testing::ToolRun run = eval({"eval", file, rec_dir_, "--json", json_file});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("warning: 3 poses"), std::string::npos) << run.out;
  const std::string json = testing::readFile(json_file);
  EXPECT_EQ(jsonNumberAt(json, {"poses", "unmatched"}), 3.0);
  EXPECT_EQ(jsonNumberAt(json, {"poses", "matched"}), static_cast<double>(rec_.groundtruth.size()));
  EXPECT_NEAR(jsonNumberAt(json, {"ape_m", "3d", "max"}), 1.3, 2e-6);  // the far poses are not in it
}

TEST_F(RiloEval, MalformedEstimateExitsWithOneNamingLineAndField) {
  const std::string file = (dir_ / "bad.tum").string();
  testing::writeFile(file, "# t x y z qx qy qz qw\n1.0 0 0 0 0 0 0 1\n1.02 0 oops 0 0 0 0 1\n");
  const testing::ToolRun run = eval({"eval", file, rec_dir_});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find(file + ":3: field 3 (y): 'oops' is not a number"), std::string::npos) << run.err;
}

TEST_F(RiloEval, BadInputExitsWithOne) {
  const std::string est = (dir_ / "est.tum").string();
  writeTum(est, offsetTruth(rec_));
  struct Case {
    std::vector<std::string> args;
    std::string message;
  };
  const std::string empty = (dir_ / "empty.tum").string();
  testing::writeFile(empty, "# nothing\n");
  const std::string no_truth = (dir_ / "no-truth").string();
  for (const char* f : {"anchors.csv", "imu.csv", "meta.yaml", "range.csv", "tags.csv"}) {
    testing::writeFile(dir_ / "no-truth" / f, testing::readFile(testing::officeDemoDir() / f));
  }
  const std::vector<Case> cases = {
      {{"eval", (dir_ / "missing.tum").string(), rec_dir_}, "missing.tum: cannot open"},
      {{"eval", empty, rec_dir_}, "no poses"},
      {{"eval", est, "/nonexistent/recording"}, "/nonexistent/recording"},
      {{"eval", est, no_truth}, "has no ground truth"},
      {{"eval", est, rec_dir_, "--max-dt-ms", "-1"}, "--max-dt-ms"},
      {{"eval", est, rec_dir_, "--rpe-delta-m", "0"}, "--rpe-delta-m"},
      {{"eval", est, rec_dir_, "--max-dt-ms", "abc"}, "--max-dt-ms: 'abc' is not a number"},
      {{"eval", est, rec_dir_, "--rpe-delta-s", "nan"}, "--rpe-delta-s"},
      {{"eval", est, rec_dir_, "--json", "/nonexistent/dir/out.json"}, "cannot write /nonexistent/dir/out.json"},
  };
  for (const Case& c : cases) {
    const testing::ToolRun run = eval(c.args);
    EXPECT_EQ(run.exit_code, 1) << c.message << "\n" << run.err;
    EXPECT_NE(run.err.find("rilo eval: "), std::string::npos) << run.err;
    EXPECT_NE(run.err.find(c.message), std::string::npos) << run.err;
  }
}

TEST_F(RiloEval, HelpDescribesTheOptions) {
  const testing::ToolRun run = eval({"eval", "--help"});
  EXPECT_EQ(run.exit_code, 0);
  for (const char* text : {"EST", "REC", "--json", "--max-dt-ms", "--rpe-delta-s", "--rpe-delta-m", "RPE"}) {
    EXPECT_NE(run.out.find(text), std::string::npos) << text << "\n" << run.out;
  }
}

}  // namespace
}  // namespace rilo
