#pragma once
// DW3000 SPI transaction headers (hardware-notes section 1):
//  short header    1 byte : b7 R/W (1 = write), b6 0, b5..1 file, b0 0 (offset 0)
//  extended header 2 bytes: b7 R/W, b6 1, b5..1 file, b0 offset bit 6;
//                           offset bits 5..0 in b7..2, b1..0 mode
//                           (00 plain, 01/10/11 masked AND-OR write of 8/16/32 bits)
//  fast command    1 byte : 0x81 | cmd << 1
// and the CRC-8 (x^8 + x^2 + x + 1, init 0, over header and body) of the
// optional SPI CRC mode. Pure functions, no allocation.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "hal/dw3000/registers.h"

namespace rilo::dw3000 {

enum class AccessMode : std::uint8_t { kPlain = 0, kMask8 = 1, kMask16 = 2, kMask32 = 3 };

struct SpiHeader {
  std::array<std::uint8_t, 2> bytes{};
  std::size_t size = 0;  ///< 1 (short) or 2 (extended)
  std::span<const std::uint8_t> view() const { return {bytes.data(), size}; }
};

/// True if the address fits the header fields (file <= 0x1F, offset <= 0x7F).
constexpr bool isValidAddress(RegAddr addr) { return addr.file <= 0x1F && addr.offset <= 0x7F; }

/// Header for a read or write of `addr`: the short form when the offset is 0
/// and the access plain, the extended form otherwise. Precondition:
/// isValidAddress(addr) (out-of-range bits are masked off).
SpiHeader encodeHeader(RegAddr addr, bool write, AccessMode mode = AccessMode::kPlain) noexcept;

/// Fast command byte, e.g. TX_W4R (0x0C) -> 0x99. Precondition: cmd <= 0x1F.
constexpr std::uint8_t encodeFastCommand(std::uint8_t cmd) {
  return static_cast<std::uint8_t>(0x81u | ((cmd & 0x1Fu) << 1));
}

/// Body size of a masked write: AND mask then OR mask, each 1/2/4 bytes.
constexpr std::size_t maskedBodySize(AccessMode mode) {
  switch (mode) {
    case AccessMode::kMask8: return 2;
    case AccessMode::kMask16: return 4;
    case AccessMode::kMask32: return 8;
    case AccessMode::kPlain: break;
  }
  return 0;
}

enum class HeaderKind : std::uint8_t { kShort, kExtended, kFastCommand };

struct DecodedHeader {
  HeaderKind kind = HeaderKind::kShort;
  bool write = false;
  RegAddr addr{};
  AccessMode mode = AccessMode::kPlain;
  std::uint8_t fast_command = 0;
  std::size_t size = 0;  ///< header bytes consumed
};

/// Parse the header at the start of `bytes`. False if too short or not a
/// valid header (b6 = 0 and b0 = 1 without b7 is no DW3000 header).
bool decodeHeader(std::span<const std::uint8_t> bytes, DecodedHeader& out) noexcept;

/// CRC-8, polynomial x^8 + x^2 + x + 1 (0x07), MSB first, no reflection;
/// chain calls by passing the previous result as `crc`.
std::uint8_t crc8(std::span<const std::uint8_t> bytes, std::uint8_t crc = 0) noexcept;

}  // namespace rilo::dw3000
