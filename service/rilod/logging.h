#pragma once
// Where rilod's log goes (issue 37). Under systemd, when stderr is the
// journal's stream (JOURNAL_STREAM names its device and inode), straight to
// journald through spdlog's systemd sink: every line carries its priority, so
// `journalctl -p warning` shows the warnings and errors. Elsewhere (a
// terminal, a pipe, a test) the console with spdlog's usual pattern.
#include <spdlog/logger.h>

#include <memory>
#include <string_view>

namespace rilo {

/// Whether `journal_stream` ("<device>:<inode>", systemd's JOURNAL_STREAM;
/// null or empty: not under journald) names the file open on `fd`.
bool isJournalStream(const char* journal_stream, int fd);

/// The logger for rilod: journald's sink when `to_journal`, else the console.
std::shared_ptr<spdlog::logger> makeServiceLogger(bool to_journal);

/// Installs makeServiceLogger(isJournalStream(getenv("JOURNAL_STREAM"), 2))
/// as spdlog's default logger; returns whether it logs to journald.
bool setUpServiceLogging();

}  // namespace rilo
