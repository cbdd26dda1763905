#pragma once
// Where the tests find things: the source tree (committed recordings), the
// folder of the running test binary (rilo and rilod are built beside it), and
// whole-file read/write. Shared by the service and evaluation tests.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rilo::testing {

/// The repository root: RILO_SOURCE_DIR if set, else derived from this
/// header's path (the build passes absolute source paths to the compiler).
inline std::filesystem::path sourceDir() {
  if (const char* env = std::getenv("RILO_SOURCE_DIR"); env != nullptr && env[0] != '\0') return env;
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path();
}

/// The running test binary, and its folder (build/bin: rilod and rilo live there too).
inline std::filesystem::path testBinary() { return std::filesystem::read_symlink("/proc/self/exe"); }
inline std::filesystem::path binaryDir() { return testBinary().parent_path(); }

inline void writeFile(const std::filesystem::path& path, std::string_view text) {
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("writeFile: cannot write " + path.string());
}

/// The whole file; empty when it cannot be opened (`found`, if given, says which).
inline std::string readFile(const std::filesystem::path& path, bool* found = nullptr) {
  std::ifstream in(path, std::ios::binary);
  if (found != nullptr) *found = static_cast<bool>(in);
  if (!in) return {};
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace rilo::testing
