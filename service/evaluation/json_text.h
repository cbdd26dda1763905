#pragma once
// JSON text for the tools' summary files (summary.json, eval --json): string
// quoting with escapes. The files are small and flat, so no JSON library.
#include <string>

namespace rilo {

/// `text` as a quoted JSON string ('"', '\\' and control characters escaped).
std::string jsonString(const std::string& text);

}  // namespace rilo
