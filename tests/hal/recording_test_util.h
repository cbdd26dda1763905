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

namespace rilo::testing {

/// Fresh empty folder under the system temp dir, removed on destruction.
class TempDir {
 public:
  TempDir() {
    static std::atomic<int> counter{0};
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    const std::string name = info != nullptr ? std::string(info->test_suite_name()) + "_" + info->name() : "x";
    path_ = std::filesystem::temp_directory_path() /
            ("rilo_rec_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + "_" + name);
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::filesystem::path& path() const { return path_; }
  std::filesystem::path operator/(std::string_view name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

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
