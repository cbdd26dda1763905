#include "rilod/logging.h"

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

namespace rilo {

bool isJournalStream(const char* journal_stream, int fd) {
  if (journal_stream == nullptr || journal_stream[0] == '\0') return false;
  // systemd.exec(5): compare with the fd's st_dev and st_ino, since the
  // variable is inherited by children whose stderr may go elsewhere.
  char* end = nullptr;
  const unsigned long long dev = std::strtoull(journal_stream, &end, 10);
  if (end == journal_stream || *end != ':') return false;
  const char* ino_text = end + 1;
  const unsigned long long ino = std::strtoull(ino_text, &end, 10);
  if (end == ino_text || *end != '\0') return false;
  struct stat st {};
  if (::fstat(fd, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev && static_cast<unsigned long long>(st.st_ino) == ino;
}

std::shared_ptr<spdlog::logger> makeServiceLogger(bool to_journal) {
  if (to_journal) {
    // journald stamps and ranks each entry itself: the message alone.
    auto sink = std::make_shared<spdlog::sinks::systemd_sink_mt>("rilod");
    return std::make_shared<spdlog::logger>("rilod", std::move(sink));
  }
  auto logger = std::make_shared<spdlog::logger>("rilod", std::make_shared<spdlog::sinks::stdout_color_sink_mt>());
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  return logger;
}

bool setUpServiceLogging() {
  const bool journal = isJournalStream(std::getenv("JOURNAL_STREAM"), STDERR_FILENO);
  spdlog::set_default_logger(makeServiceLogger(journal));
  return journal;
}

}  // namespace rilo
