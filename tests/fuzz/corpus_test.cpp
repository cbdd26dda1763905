// Every committed fuzzing input (tests/fuzz/corpus/<target>/, grown by
// scripts/fuzz.sh) through its target on every build: a parser that throws
// anything but its documented error on one of them, or crashes, fails here.
#include <gtest/gtest.h>

#include <cstdint>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/targets/fuzz_targets.h"
#include "support/source_tree.h"

namespace rilo {
namespace {

struct Target {
  const char* name;
  int (*run)(const std::uint8_t*, std::size_t);
};

const Target kTargets[] = {{"recording_csv", fuzz::recordingCsv}, {"meta_yaml", fuzz::metaYaml},
                           {"rilod_config", fuzz::rilodConfig},     {"tum_trajectory", fuzz::tumTrajectory},
                           {"bmi263_fifo", fuzz::bmi263Fifo},       {"dw3000_frame", fuzz::dw3000Frame}};

class FuzzCorpus : public ::testing::TestWithParam<Target> {};

TEST_P(FuzzCorpus, EveryCommittedInputIsTakenOrRefusedWithItsOwnError) {
  const std::filesystem::path dir = testing::sourceDir() / "tests" / "fuzz" / "corpus" / GetParam().name;
  ASSERT_TRUE(std::filesystem::is_directory(dir)) << dir;
  std::size_t inputs = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir)) {
    if (!entry.is_regular_file()) continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    try {
      EXPECT_EQ(GetParam().run(reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size()), 0);
    } catch (const std::exception& e) {
      ADD_FAILURE() << entry.path() << ": " << e.what();
    }
    ++inputs;
  }
  EXPECT_GE(inputs, 3u) << "the corpus of " << GetParam().name << " is nearly empty";
  std::printf("%s: %zu inputs\n", GetParam().name, inputs);
}

INSTANTIATE_TEST_SUITE_P(Targets, FuzzCorpus, ::testing::ValuesIn(kTargets),
                         [](const ::testing::TestParamInfo<Target>& p) { return std::string(p.param.name); });

}  // namespace
}  // namespace rilo
