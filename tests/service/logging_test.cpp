// rilod's log destination (issue 37): journald with priorities only when
// stderr really is the journal's stream, the console otherwise.
#include "rilod/logging.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <spdlog/sinks/systemd_sink.h>
#include <sys/stat.h>
#include <unistd.h>

#include <string>

#include "support/temp_dir.h"

namespace rilo {
namespace {

TEST(ServiceLogging, JournalStreamMustNameTheFileOnTheDescriptor) {
  testing::TempDir dir("logging");
  const std::string path = (dir / "stderr.txt").string();
  const int fd = ::open(path.c_str(), O_CREAT | O_WRONLY, 0600);
  ASSERT_GE(fd, 0);
  struct stat st {};
  ASSERT_EQ(::fstat(fd, &st), 0);
  const std::string same = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  const std::string other = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino + 1);
  EXPECT_TRUE(isJournalStream(same.c_str(), fd));
  EXPECT_FALSE(isJournalStream(other.c_str(), fd));  // inherited by a child writing elsewhere
  EXPECT_FALSE(isJournalStream(nullptr, fd));
  EXPECT_FALSE(isJournalStream("", fd));
  EXPECT_FALSE(isJournalStream("12", fd));
  EXPECT_FALSE(isJournalStream("12:x", fd));
  EXPECT_FALSE(isJournalStream((same + "9z").c_str(), fd));
  ::close(fd);
  EXPECT_FALSE(isJournalStream(same.c_str(), fd));  // a closed descriptor
}

TEST(ServiceLogging, TheJournalLoggerSendsThroughSystemdsSinkTheConsoleOneDoesNot) {
  const auto journal = makeServiceLogger(true);
  ASSERT_EQ(journal->sinks().size(), 1u);
  EXPECT_NE(std::dynamic_pointer_cast<spdlog::sinks::systemd_sink_mt>(journal->sinks()[0]), nullptr);
  const auto console = makeServiceLogger(false);
  ASSERT_EQ(console->sinks().size(), 1u);
  EXPECT_EQ(std::dynamic_pointer_cast<spdlog::sinks::systemd_sink_mt>(console->sinks()[0]), nullptr);
  EXPECT_EQ(console->name(), "rilod");
}

}  // namespace
}  // namespace rilo
