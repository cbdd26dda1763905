// Unsigned options of `rilo` refuse negative numbers (issue 39: CLI11
// wrapped them round: `rilo sim --seed -3` simulated seed
// 18446744073709551613 and `rilo listen --count -1` ran for ever). Each
// call fails at parsing, naming the option, before doing anything.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "eval_test_support.h"

namespace rilo {
namespace {

TEST(RiloUnsignedOptions, RefuseANegativeNumberNamingTheOption) {
  testing::TempDir dir("rilo-unsigned");
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  const std::vector<std::pair<std::vector<std::string>, std::string>> calls = {
      {{"sim", (dir / "never").string(), "--seed", "-3"}, "--seed"},
      {{"demo", "--seed", "-1"}, "--seed"},
      {{"listen", "--count", "-1", "--timeout", "1"}, "--count"},  // a timeout: never hang if the check regressed
      {{"listen", "--domain", "-1", "--timeout", "1"}, "--domain"},
      {{"replay", rec, "--out", (dir / "never").string(), "--reception-seed", "-2"}, "--reception-seed"},
      {{"report", "--out", (dir / "never").string(), "--sim-seeds", "1,-2"}, "--sim-seeds"},
  };
  for (const auto& [args, option] : calls) {
    const testing::ToolRun run = testing::runRilo(args, dir.path());
    EXPECT_NE(run.exit_code, 0) << args[0] << " " << option;
    EXPECT_NE(run.err.find(option), std::string::npos) << args[0] << ": " << run.err;
    EXPECT_NE(run.err.find("must not be negative"), std::string::npos) << args[0] << ": " << run.err;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "never"));
  // Zero and positive values still parse (a 3 s simulation).
  const testing::ToolRun ok = testing::runRilo({"sim", (dir / "seed0").string(), "--seed", "0", "--seconds", "3"}, dir.path());
  EXPECT_EQ(ok.exit_code, 0) << ok.err;
}

}  // namespace
}  // namespace rilo
