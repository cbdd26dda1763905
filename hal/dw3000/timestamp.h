#pragma once
// DW3000 40-bit device time: 1 unit = 1/(499.2 MHz * 128) = 15.65 ps, wraps
// every 2^40 units (~17.2 s). Differences are taken modulo 2^40 and read as
// signed, so any interval shorter than half the wrap (~8.6 s) is exact across
// a wrap.
#include <cstdint>

namespace rilo::dw3000 {

inline constexpr int kTimestampBits = 40;
inline constexpr std::uint64_t kTimestampModulus = std::uint64_t{1} << kTimestampBits;
inline constexpr std::uint64_t kTimestampMask = kTimestampModulus - 1;
/// Device clock frequency (Hz) and time unit (s).
inline constexpr double kDeviceClockHz = 499.2e6 * 128.0;
inline constexpr double kDeviceTimeUnitS = 1.0 / kDeviceClockHz;
/// UWB microsecond (W4R_TIM, RX_FWTO units): 512 / 499.2 MHz = 1.0256 us = 65536 device units.
inline constexpr double kUwbMicrosecondS = 512.0 / 499.2e6;
inline constexpr std::uint64_t kDeviceUnitsPerUwbMicrosecond = 65536;
/// Speed of light in air used for ranges (m/s), as in the notes.
inline constexpr double kSpeedOfLightAirMps = 299702547.0;
/// Distance light travels in one device unit (m), ~4.69 mm.
inline constexpr double kMetersPerDeviceUnit = kSpeedOfLightAirMps * kDeviceTimeUnitS;

/// (later - earlier) modulo 2^40, as a signed value in [-2^39, 2^39).
constexpr std::int64_t timestampDiff(std::uint64_t later, std::uint64_t earlier) {
  const std::uint64_t d = (later - earlier) & kTimestampMask;
  return d >= (kTimestampModulus >> 1) ? static_cast<std::int64_t>(d) - static_cast<std::int64_t>(kTimestampModulus)
                                       : static_cast<std::int64_t>(d);
}

/// t + delta modulo 2^40.
constexpr std::uint64_t timestampAdd(std::uint64_t t, std::int64_t delta) {
  return (t + static_cast<std::uint64_t>(delta)) & kTimestampMask;
}

/// Little-endian 5-byte timestamp.
constexpr std::uint64_t readTimestamp40(const std::uint8_t* bytes) {
  std::uint64_t v = 0;
  for (int i = 4; i >= 0; --i) v = (v << 8) | bytes[i];
  return v;
}
constexpr void writeTimestamp40(std::uint64_t t, std::uint8_t* bytes) {
  for (int i = 0; i < 5; ++i) bytes[i] = static_cast<std::uint8_t>((t >> (8 * i)) & 0xFFu);
}

/// Microseconds to whole UWB microseconds (rounded).
constexpr std::uint32_t uwbMicrosecondsFromUs(double us) {
  return static_cast<std::uint32_t>(us * 1e-6 / kUwbMicrosecondS + 0.5);
}

}  // namespace rilo::dw3000
