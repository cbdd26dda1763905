#pragma once
// Small formatters for the DW3000 driver's fault and bring-up messages.
#include <cstdint>
#include <cstdio>
#include <string>

namespace rilo::dw3000 {

inline std::string hex8(std::uint32_t v) {
  char text[8];
  std::snprintf(text, sizeof text, "0x%02X", v & 0xFFu);
  return text;
}

inline std::string hex16(std::uint32_t v) {
  char text[10];
  std::snprintf(text, sizeof text, "0x%04X", v & 0xFFFFu);
  return text;
}

inline std::string hex32(std::uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08X", v);
  return text;
}

/// A duration in ms for people ("20 ms", "0.25 ms").
inline std::string msText(std::int64_t ns) {
  char text[32];
  const double ms = static_cast<double>(ns) * 1e-6;
  std::snprintf(text, sizeof text, ms >= 1.0 ? "%.0f ms" : "%.3g ms", ms);
  return text;
}

}  // namespace rilo::dw3000
