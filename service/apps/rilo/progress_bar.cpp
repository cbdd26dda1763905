#include "progress_bar.h"

#include <spdlog/spdlog.h>
#include <unistd.h>

#include <cstdio>
#include <utility>

namespace rilo::tool {

std::string formatDuration(double s) {
  const long total = static_cast<long>(s + 0.5);
  char buf[32];
  if (total >= 3600) {
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", total / 3600, (total / 60) % 60, total % 60);
  } else {
    std::snprintf(buf, sizeof buf, "%ld:%02ld", total / 60, total % 60);
  }
  return buf;
}

ProgressBar::ProgressBar(std::string command, std::string what)
    : command_(std::move(command)), what_(std::move(what)), tty_(::isatty(STDERR_FILENO) == 1) {}

ProgressBar::~ProgressBar() {
  if (tty_ && printed_) std::fputc('\n', stderr);
}

void ProgressBar::operator()(std::size_t done, std::size_t total) {
  const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const int decile = total ? static_cast<int>(10 * done / total) : 10;
  if (!tty_ && decile <= last_decile_) return;
  last_decile_ = decile;
  constexpr int kWidth = 30;
  const int filled = total ? static_cast<int>(kWidth * done / total) : kWidth;
  std::string bar(static_cast<std::size_t>(filled), '#');
  bar.append(static_cast<std::size_t>(kWidth - filled), '.');
  std::string left;
  if (done > 0 && done < total) {
    left = ", ~" + formatDuration(elapsed / static_cast<double>(done) * static_cast<double>(total - done)) + " left";
  }
  if (!tty_) {  // a log line per tenth (a pipe, journald)
    spdlog::info("[{}] {}/{} {}, {} elapsed{}", bar, done, total, what_, formatDuration(elapsed), left);
    return;
  }
  // A live bar on the terminal, redrawn in place: not a log line.
  std::fprintf(stderr, "\rrilo %s: [%s] %zu/%zu %s, %s elapsed%s   ", command_.c_str(), bar.c_str(), done, total, what_.c_str(),
               formatDuration(elapsed).c_str(), left.c_str());
  std::fflush(stderr);
  printed_ = true;
}

}  // namespace rilo::tool
