#pragma once
// Helpers shared by the recording tests: scratch folders and file text.
#include <gtest/gtest.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "hal/recording/recording_error.h"
#include "support/temp_dir.h"

namespace rilo::testing {

inline void writeText(const std::filesystem::path& p, std::string_view text) {
  std::ofstream f(p, std::ios::binary | std::ios::trunc);
  f.write(text.data(), static_cast<std::streamsize>(text.size()));
}

inline std::string readText(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::string text;
  char buf[4096];
  while (f.read(buf, sizeof(buf)) || f.gcount() > 0) text.append(buf, static_cast<std::size_t>(f.gcount()));
  return text;
}

/// Runs `fn`, which must throw RecordingError; returns it.
template <typename Fn>
RecordingError expectRecordingError(Fn&& fn) {
  try {
    fn();
  } catch (const RecordingError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a RecordingError";
  return RecordingError("", 0, "", "no error");
}

}  // namespace rilo::testing
