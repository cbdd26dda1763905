#pragma once
// Helpers of the evaluation tests: the source tree's and the binaries'
// locations, running the rilo tool as a subprocess, files, and a minimal
// lookup in the JSON `rilo eval --json` writes.
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "support/source_tree.h"
#include "support/temp_dir.h"

namespace rilo::testing {

inline std::filesystem::path officeDemoDir() { return sourceDir() / "tests" / "data" / "office-demo"; }

struct ToolRun {
  int exit_code = -1;  ///< -1 if the process did not exit normally
  std::string out, err;
};

/// Runs build/bin/rilo with `args`, stdout and stderr captured through files in `scratch`.
inline ToolRun runRilo(const std::vector<std::string>& args, const std::filesystem::path& scratch) {
  const std::string exe = (binaryDir() / "rilo").string();
  const std::string out_file = (scratch / "rilo.stdout").string();
  const std::string err_file = (scratch / "rilo.stderr").string();
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(exe.c_str()));
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    const int out_fd = ::open(out_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int err_fd = ::open(err_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (out_fd < 0 || err_fd < 0 || ::dup2(out_fd, STDOUT_FILENO) < 0 || ::dup2(err_fd, STDERR_FILENO) < 0) ::_exit(126);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  ToolRun run;
  int status = 0;
  if (pid < 0 || ::waitpid(pid, &status, 0) != pid) return run;
  if (WIFEXITED(status)) run.exit_code = WEXITSTATUS(status);
  run.out = readFile(out_file);
  run.err = readFile(err_file);
  return run;
}

/// The number after the last key of `path`, each key searched after the
/// previous one ("ape_m", "3d", "mean"); throws if a key is missing or the
/// value is not a number (e.g. null).
inline double jsonNumberAt(const std::string& json, std::initializer_list<std::string_view> path) {
  std::size_t pos = 0;
  for (std::string_view key : path) {
    std::string quoted = "\"";  // appended: GCC 12 warns falsely on `"\"" + std::string(...)`
    quoted += key;
    quoted += "\":";
    pos = json.find(quoted, pos);
    if (pos == std::string::npos) throw std::runtime_error("jsonNumberAt: no key " + std::string(key));
    pos += quoted.size();
  }
  const char* begin = json.c_str() + pos;
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin) throw std::runtime_error("jsonNumberAt: not a number at " + json.substr(pos, 20));
  return v;
}

}  // namespace rilo::testing
