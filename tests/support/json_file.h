#pragma once
// Reads a JSON file the tools wrote (summary.json, eval --json) with the same
// library that wrote it: a malformed file fails the test with the parser's
// message instead of a string search passing by accident.
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

namespace rilo::testing {

inline nlohmann::json readJsonFile(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot open " + file.string());
  std::stringstream text;
  text << in.rdbuf();
  try {
    return nlohmann::json::parse(text.str());
  } catch (const nlohmann::json::parse_error& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
}

}  // namespace rilo::testing
