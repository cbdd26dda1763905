// `rilo accuracy` as a subprocess on the committed office demo: the table
// with the shipped configuration, a second run compared against the first,
// and bad input refused with a message that names it.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "eval_test_support.h"
#include "evaluation/accuracy_table.h"

namespace rilo {
namespace {

class RiloAccuracy : public ::testing::Test {
 protected:
  testing::ToolRun accuracy(const std::vector<std::string>& args) {
    std::vector<std::string> all{"accuracy"};
    all.insert(all.end(), args.begin(), args.end());
    return testing::runRilo(all, dir_.path());
  }
  testing::TempDir dir_{"rilo-accuracy"};
  const std::string demo_ = testing::officeDemoDir().string();
};

TEST_F(RiloAccuracy, WritesTheTableAndComparesWithAnEarlierRun) {
  const std::string first = (dir_ / "first").string();
  testing::ToolRun run = accuracy({demo_, "--out", first, "--rates", "40", "--jobs", "1"});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  EXPECT_NE(run.out.find("rilo accuracy: 2 runs on 1 recordings (0 never started, 0 failed)"), std::string::npos)
      << run.out;
  const std::vector<AccuracyRow> rows = readAccuracyCsv(dir_ / "first" / "accuracy.csv");
  ASSERT_EQ(rows.size(), 2u);  // as recorded and without the first-path column; grouped by the parent folder
  EXPECT_EQ(rows[0].set, "data, all ranges");
  EXPECT_EQ(rows[1].set, "data, all ranges, first path removed");
  for (const AccuracyRow& r : rows) {
    EXPECT_EQ(r.recording, "office-demo");
    EXPECT_TRUE(r.started);
    EXPECT_LT(r.online_mean_m, 0.5);  // the shipped configuration on its own demo: ~0.2 m
  }
  const std::string md = testing::readFile(dir_ / "first" / "accuracy.md");
  EXPECT_NE(md.find("# Accuracy: config/rilod.yaml (built in)"), std::string::npos) << md;
  EXPECT_NE(md.find("| data, all ranges | 1 | 1 |"), std::string::npos) << md;
  EXPECT_NE(md.find("| data, all ranges | office-demo |"), std::string::npos) << md;

  // The same estimator again, compared: both rows matched, the set said compared over 1.
  const std::string second = (dir_ / "second").string();
  run = accuracy({demo_, "--out", second, "--rates", "40", "--only-as-recorded", "--compare",
                  (dir_ / "first" / "accuracy.csv").string()});
  ASSERT_EQ(run.exit_code, 0) << run.out << run.err;
  const std::string compared = testing::readFile(dir_ / "second" / "accuracy.md");
  EXPECT_NE(compared.find("| set | recordings | compared | started |"), std::string::npos) << compared;
  EXPECT_NE(compared.find("| data, all ranges | 1 | 1 | 1 |"), std::string::npos) << compared;
  // The same estimator on the same recording: no figure changed in print.
  std::istringstream lines(compared);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("|", 0) == 0) {
      EXPECT_EQ(line.find("->"), std::string::npos) << line;
    }
  }
  EXPECT_EQ(readAccuracyCsv(dir_ / "second" / "accuracy.csv").size(), 1u);
}

TEST_F(RiloAccuracy, BadInputIsRefusedByName) {
  testing::ToolRun run = accuracy({"--out", (dir_ / "x").string()});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find("give recordings (REC...) or --own-sims"), std::string::npos) << run.err;

  const std::filesystem::path bad = dir_ / "bad.csv";
  std::ofstream(bad) << "recording,online\n";
  run = accuracy({demo_, "--out", (dir_ / "x").string(), "--compare", bad.string()});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find(bad.string() + ":1: not an accuracy.csv"), std::string::npos) << run.err;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x" / "accuracy.csv"));  // refused before any run

  run = accuracy({demo_, "--out", (dir_ / "x").string(), "--rates", "0"});
  EXPECT_NE(run.exit_code, 0);
  run = accuracy({(dir_ / "missing").string(), "--out", (dir_ / "x").string()});
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("missing"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace rilo
