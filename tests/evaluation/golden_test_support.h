#pragma once
// Helpers of the golden-trace test: where the source tree and the build tree
// are, and whole-file read/write. Own namespace, so this header never clashes
// with the other areas' support headers in one test binary.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>

namespace rilo::testing::golden {

/// The repository root: RILO_SOURCE_DIR if set, else derived from this
/// header's path (the build passes absolute source paths to the compiler).
inline std::filesystem::path sourceDir() {
  if (const char* env = std::getenv("RILO_SOURCE_DIR"); env != nullptr && env[0] != '\0') return env;
  return std::filesystem::path(__FILE__).parent_path().parent_path().parent_path();
}

/// The build tree: the parent of the running test binary's folder (build/bin).
inline std::filesystem::path buildDir() {
  return std::filesystem::read_symlink("/proc/self/exe").parent_path().parent_path();
}

/// The running test binary (for the "accept" command line).
inline std::filesystem::path testBinary() { return std::filesystem::read_symlink("/proc/self/exe"); }

inline void writeFile(const std::filesystem::path& path, std::string_view text) {
  if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("writeFile: cannot write " + path.string());
}

/// Whole file, or std::nullopt-like empty result signalled by `found`.
inline std::string readFile(const std::filesystem::path& path, bool* found = nullptr) {
  std::ifstream in(path, std::ios::binary);
  if (found != nullptr) *found = static_cast<bool>(in);
  if (!in) return {};
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/// True when the environment asks to rewrite golden files (RILO_UPDATE_GOLDEN=1).
inline bool updateGoldenRequested() {
  const char* env = std::getenv("RILO_UPDATE_GOLDEN");
  return env != nullptr && std::string_view(env) == "1";
}

}  // namespace rilo::testing::golden
