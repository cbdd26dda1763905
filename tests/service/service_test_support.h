#pragma once
// Helpers of the service tests: the source tree's location, temporary
// folders and files.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

#include "support/temp_dir.h"

namespace rilo::testing {

/// The repository root: RILO_SOURCE_DIR if set, else derived from this
/// header's path (the build passes absolute source paths to the compiler).
inline std::filesystem::path sourceDir() {
  if (const char* env = std::getenv("RILO_SOURCE_DIR"); env != nullptr && env[0] != '\0') return env;
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path();
}

/// The folder of the running test binary (build/bin: rilod and rilo live there too).
inline std::filesystem::path binaryDir() { return std::filesystem::read_symlink("/proc/self/exe").parent_path(); }

inline void writeFile(const std::filesystem::path& path, std::string_view text) {
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("writeFile: cannot write " + path.string());
}

inline std::string readFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return {};
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace rilo::testing
