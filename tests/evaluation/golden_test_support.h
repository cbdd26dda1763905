#pragma once
// Helpers of the golden-trace test: the build tree and the request to rewrite
// golden files (paths and file I/O: support/source_tree.h).
#include <cstdlib>
#include <filesystem>
#include <string_view>

#include "support/source_tree.h"

namespace rilo::testing::golden {

using testing::readFile;
using testing::sourceDir;
using testing::testBinary;
using testing::writeFile;

/// The build tree: the parent of the running test binary's folder (build/bin).
inline std::filesystem::path buildDir() { return binaryDir().parent_path(); }

/// True when the environment asks to rewrite golden files (RILO_UPDATE_GOLDEN=1).
inline bool updateGoldenRequested() {
  const char* env = std::getenv("RILO_UPDATE_GOLDEN");
  return env != nullptr && std::string_view(env) == "1";
}

}  // namespace rilo::testing::golden
