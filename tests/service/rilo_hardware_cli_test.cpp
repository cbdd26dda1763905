// `rilo probe` and `rilo record` as processes: on a machine without the
// board's device nodes they fail with exit code 2 and a message naming the
// device path; configuration problems are exit code 1.
#include <gtest/gtest.h>

#include <string>

#include "evaluation/eval_test_support.h"
#include "service/emulated_board.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

using testing::runRilo;
using testing::TempDir;

// Device nodes no machine has (the configuration insists on /dev/ paths).
const std::string kMissingSpi = "/dev/rilo-test-no-spidev9.9";
const std::string kMissingI2c = "/dev/rilo-test-no-i2c-9";

/// The board's configuration with the device nodes moved to paths that do not exist.
std::string missingNodesConfig(const TempDir& dir) {
  std::string yaml = testing::boardYaml();
  yaml.replace(yaml.find("/dev/spidev0.0"), 14, kMissingSpi);
  yaml.replace(yaml.find("/dev/i2c-1"), 10, kMissingI2c);
  const auto file = dir / "rilod.yaml";
  testing::writeFile(file, yaml);
  testing::writeBlob(dir / "blob.bin");
  return file.string();
}

TEST(RiloProbeCli, MissingDevicesExitTwoNamingThePaths) {
  TempDir dir("probe-cli");
  const std::string config = missingNodesConfig(dir);
  const testing::ToolRun run = runRilo({"probe", "--config", config, "--seconds", "0.1"}, dir.path());
  EXPECT_EQ(run.exit_code, 2) << run.out << run.err;
  EXPECT_NE(run.err.find(kMissingSpi), std::string::npos) << run.err;
  EXPECT_NE(run.err.find(kMissingI2c + "@0x68"), std::string::npos) << run.err;
  EXPECT_NE(run.out.find("DWM3000 on " + kMissingSpi + ": FAILED"), std::string::npos) << run.out;
}

TEST(RiloProbeCli, JsonReportOnStdout) {
  TempDir dir("probe-cli");
  const std::string config = missingNodesConfig(dir);
  const testing::ToolRun run = runRilo({"probe", "--config", config, "--json", "--seconds", "0.1"}, dir.path());
  EXPECT_EQ(run.exit_code, 2) << run.out << run.err;
  ASSERT_FALSE(run.out.empty());
  EXPECT_EQ(run.out.front(), '{') << run.out;
  EXPECT_NE(run.out.find("\"ok\": false"), std::string::npos) << run.out;
  EXPECT_EQ(testing::jsonNumberAt(run.out, {"exit_code"}), 2.0);
  EXPECT_NE(run.out.find("\"opened\": false"), std::string::npos) << run.out;
}

TEST(RiloProbeCli, AReplayConfigurationIsExitOne) {
  TempDir dir("probe-cli");
  std::string yaml = testing::boardYaml();
  yaml.replace(yaml.find("mode: hardware"), 14, "mode: replay\n  replay: {path: rec}");
  testing::writeFile(dir / "rilod.yaml", yaml);
  const testing::ToolRun run = runRilo({"probe", "--config", (dir / "rilod.yaml").string()}, dir.path());
  EXPECT_EQ(run.exit_code, 1) << run.out << run.err;
  EXPECT_NE(run.err.find("sources.mode is replay"), std::string::npos) << run.err;
}

TEST(RiloRecordCli, MissingDevicesExitTwoNamingThePath) {
  TempDir dir("record-cli");
  const std::string config = missingNodesConfig(dir);
  const testing::ToolRun run =
      runRilo({"record", "--config", config, "--out", (dir / "rec").string(), "--seconds", "1"}, dir.path());
  EXPECT_EQ(run.exit_code, 2) << run.out << run.err;
  EXPECT_NE(run.err.find(kMissingSpi), std::string::npos) << run.err;
  EXPECT_NE(run.err.find("sources.hardware.uwb.spi_device"), std::string::npos) << run.err;
}

TEST(RiloRecordCli, OutIsRequired) {
  TempDir dir("record-cli");
  const std::string config = missingNodesConfig(dir);
  const testing::ToolRun run = runRilo({"record", "--config", config}, dir.path());
  EXPECT_NE(run.exit_code, 0);
  EXPECT_NE(run.err.find("--out"), std::string::npos) << run.err;
}

}  // namespace
}  // namespace rilo
