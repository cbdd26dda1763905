// --version on both programs (issue 37): the project version and the
// checkout's `git describe` at build time, exit code 0, nothing else run.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "rilo_version.h"
#include "service_test_support.h"

namespace rilo {
namespace {

/// Runs `command`, returns its standard output; `status` gets pclose's status.
std::string run(const std::string& command, int& status) {
  std::string out;
  FILE* pipe = ::popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buf[256];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) out += buf;
  status = ::pclose(pipe);
  return out;
}

TEST(Version, BothProgramsPrintTheBuildsVersionAndExit) {
  for (const char* program : {"rilo", "rilod"}) {
    int status = -1;
    const std::string out = run((testing::binaryDir() / program).string() + " --version", status);
    EXPECT_EQ(status, 0) << program;
    EXPECT_EQ(out, std::string(program) + " " + RILO_VERSION_TEXT + "\n") << program;
    EXPECT_EQ(out.rfind(std::string(program) + " 0.", 0), 0u) << out;  // the project version first
    EXPECT_NE(out.find(" ("), std::string::npos) << out;             // then git describe, or "no git"
  }
}

}  // namespace
}  // namespace rilo
