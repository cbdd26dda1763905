// `rilo sim --plan hall` as a subprocess: the open-hall session with TDoA and
// ultrasonic is written as a recording that reads back, holds exactly the
// samples of the same simulation run in-process, and the hall options are
// refused without --plan hall. Also the wearer's carry height (--body-height).
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "eval_test_support.h"
#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"
#include "sim/office_recording.h"

namespace rilo {
namespace {

class RiloSimHall : public ::testing::Test {
 protected:
  testing::ToolRun sim(const std::vector<std::string>& args) { return testing::runRilo(args, dir_.path()); }

  testing::TempDir dir_{"rilo-sim-hall"};
};

TEST_F(RiloSimHall, TdoaAndUltrasonicSessionReadsBackAsTheSimulatorWroteIt) {
  const std::string out = (dir_ / "hall").string();
  const testing::ToolRun run =
      sim({"sim", out, "--plan", "hall", "--tdoa", "--ultrasonic", "--seconds", "18", "--seed", "4"});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("plan      hall 16.0 m x 10.0 m, 2 pillars"), std::string::npos) << run.out;
  EXPECT_NE(run.out.find("TDoA NLOS"), std::string::npos) << run.out;

  const Recording rec = readRecording(out);
  EXPECT_EQ(rec.meta.description.rfind("rilo sim: 16.0 m x 10.0 m hall plan, seed 4, 8 anchors", 0), 0u)
      << rec.meta.description;
  ASSERT_TRUE(rec.meta.ranging.has_value());
  EXPECT_EQ(*rec.meta.ranging, RangingKind::kTdoa);
  EXPECT_EQ(rec.imu.size(), 14401u);  // 18 s at 800 Hz
  EXPECT_TRUE(rec.ranges.empty());
  EXPECT_GT(rec.tdoa.size(), 1500u);
  EXPECT_GT(rec.ultrasonic.size(), 100u);
  EXPECT_FALSE(rec.groundtruth.empty());
  // Eight UWB anchors around the hall, low and high in turn; four beacons on the ceiling.
  int uwb = 0, ultrasonic = 0;
  for (const Anchor& a : rec.anchors) {
    if (a.kind == AnchorKind::kUwb) {
      EXPECT_EQ(a.p_w_anchor.z() < 1.5, uwb % 2 == 0) << a.id;
      ++uwb;
    } else {
      EXPECT_NEAR(a.p_w_anchor.z(), 2.95, 1e-12);
      ++ultrasonic;
    }
  }
  EXPECT_EQ(uwb, 8);
  EXPECT_EQ(ultrasonic, 4);

  // The same session simulated in-process: byte for byte the same samples.
  sim::OfficeScenarioParams p;
  p.seed = 4;
  p.duration_s = 0.3 * 60.0;
  p.plan = sim::OfficePlanKind::kHall;
  p.tdoa.enabled = true;
  p.ultrasonic.enabled = true;
  sim::ScenarioRecordingOptions o;
  o.name = "hall";
  o.description = rec.meta.description;
  const std::filesystem::path mine = dir_ / "in-process" / "hall";
  sim::writeOfficeRecording(p, mine, o);
  for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kImuFile, recording::kTdoaFile,
                             recording::kUltrasonicFile, recording::kGroundTruthFile}) {
    EXPECT_EQ(testing::readFile(mine / f), testing::readFile(std::filesystem::path(out) / f)) << f;
  }
}

TEST_F(RiloSimHall, HallSizeOptionsResizeTheHallAndNeedPlanHall) {
  const std::string out = (dir_ / "big").string();
  const testing::ToolRun run = sim({"sim", out, "--plan", "hall", "--hall-length", "24", "--hall-width", "14",
                                    "--seconds", "6", "--anchors", "6"});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const Recording rec = readRecording(out);
  ASSERT_EQ(rec.anchors.size(), 6u);
  double x_max = 0.0, y_max = 0.0;
  for (const Anchor& a : rec.anchors) {
    x_max = std::max(x_max, a.p_w_anchor.x());
    y_max = std::max(y_max, a.p_w_anchor.y());
  }
  EXPECT_DOUBLE_EQ(x_max, 23.75);
  EXPECT_DOUBLE_EQ(y_max, 13.75);
  EXPECT_FALSE(rec.ranges.empty());

  const testing::ToolRun refused = sim({"sim", (dir_ / "no").string(), "--hall-length", "24", "--seconds", "6"});
  EXPECT_EQ(refused.exit_code, 1);
  EXPECT_NE(refused.err.find("--hall-length and --hall-width need --plan hall"), std::string::npos) << refused.err;
}

TEST_F(RiloSimHall, BodyHeightOptionCarriesTheTagAtThatHeight) {
  // A head-worn device (glasses): the walk keeps the body frame at the given
  // height, give or take the gait's bob, and the description says so.
  const std::string out = (dir_ / "glasses").string();
  const testing::ToolRun run = sim({"sim", out, "--seconds", "6", "--body-height", "1.6"});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const Recording rec = readRecording(out);
  ASSERT_FALSE(rec.groundtruth.empty());
  for (const GroundTruthPose& g : rec.groundtruth) ASSERT_NEAR(g.p_w_b.z(), 1.6, 0.06) << g.t_ns;
  EXPECT_NE(rec.meta.description.find("body frame 1.60 m above the floor"), std::string::npos) << rec.meta.description;

  // The default (chest) height is not mentioned, and out-of-range heights are refused by name.
  const testing::ToolRun chest = sim({"sim", (dir_ / "chest").string(), "--seconds", "6"});
  ASSERT_EQ(chest.exit_code, 0) << chest.out << chest.err;
  const Recording rec_chest = readRecording((dir_ / "chest").string());
  EXPECT_EQ(rec_chest.meta.description.find("body frame"), std::string::npos) << rec_chest.meta.description;
  EXPECT_NEAR(rec_chest.groundtruth.front().p_w_b.z(), 1.25, 0.06);
  const testing::ToolRun refused = sim({"sim", (dir_ / "tall").string(), "--seconds", "6", "--body-height", "2.5"});
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_NE(refused.err.find("--body-height"), std::string::npos) << refused.err;
}

}  // namespace
}  // namespace rilo
