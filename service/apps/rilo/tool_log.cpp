#include "tool_log.h"

#include <spdlog/pattern_formatter.h>
#include <spdlog/sinks/stdout_color_sinks.h>  // stderr_color_sink_mt too
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdlib>
#include <memory>
#include <string_view>

#include "rilod/logging.h"

namespace rilo::tool {
namespace {

/// %* : "warning: " / "error: " before the message, nothing for info and below
/// (a tool's info line reads as plain text, as it did with fprintf).
class LevelPrefix final : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    std::string_view prefix;
    switch (msg.level) {
      case spdlog::level::warn: prefix = "warning: "; break;
      case spdlog::level::err: prefix = "error: "; break;
      case spdlog::level::critical: prefix = "critical: "; break;
      default: return;
    }
    dest.append(prefix.data(), prefix.data() + prefix.size());
  }
  std::unique_ptr<spdlog::custom_flag_formatter> clone() const override { return std::make_unique<LevelPrefix>(); }
};

}  // namespace

void setUpToolLogging(const std::string& command) {
  const std::string name = command.empty() ? std::string("rilo") : "rilo " + command;
  std::shared_ptr<spdlog::logger> logger;
  if (isJournalStream(std::getenv("JOURNAL_STREAM"), STDERR_FILENO)) {
    // journald stamps and ranks each entry itself: the message alone.
    logger = std::make_shared<spdlog::logger>(name, std::make_shared<spdlog::sinks::systemd_sink_mt>("rilo"));
  } else {
    logger = std::make_shared<spdlog::logger>(name, std::make_shared<spdlog::sinks::stderr_color_sink_mt>());
    auto formatter = std::make_unique<spdlog::pattern_formatter>();
    formatter->add_flag<LevelPrefix>('*').set_pattern("%n: %^%*%$%v");
    logger->set_formatter(std::move(formatter));
  }
  logger->flush_on(spdlog::level::info);  // a tool's message shows before its result, as with stderr
  spdlog::set_default_logger(std::move(logger));
}

}  // namespace rilo::tool
