#include "hal/dw3000/spi_framing.h"

namespace rilo::dw3000 {

SpiHeader encodeHeader(RegAddr addr, bool write, AccessMode mode) noexcept {
  SpiHeader h;
  const std::uint8_t rw = write ? 0x80 : 0x00;
  const auto file_bits = static_cast<std::uint8_t>((addr.file & 0x1Fu) << 1);
  const std::uint8_t offset = addr.offset & 0x7Fu;
  if (offset == 0 && mode == AccessMode::kPlain) {
    h.bytes[0] = static_cast<std::uint8_t>(rw | file_bits);
    h.size = 1;
    return h;
  }
  h.bytes[0] = static_cast<std::uint8_t>(rw | 0x40u | file_bits | (offset >> 6));
  h.bytes[1] = static_cast<std::uint8_t>(((offset & 0x3Fu) << 2) | static_cast<std::uint8_t>(mode));
  h.size = 2;
  return h;
}

bool decodeHeader(std::span<const std::uint8_t> bytes, DecodedHeader& out) noexcept {
  if (bytes.empty()) return false;
  const std::uint8_t b0 = bytes[0];
  out = DecodedHeader{};
  if ((b0 & 0x40u) != 0) {
    if (bytes.size() < 2) return false;
    const std::uint8_t b1 = bytes[1];
    out.kind = HeaderKind::kExtended;
    out.write = (b0 & 0x80u) != 0;
    out.addr.file = static_cast<std::uint8_t>((b0 >> 1) & 0x1Fu);
    out.addr.offset = static_cast<std::uint8_t>(((b0 & 0x01u) << 6) | (b1 >> 2));
    out.mode = static_cast<AccessMode>(b1 & 0x03u);
    out.size = 2;
    return true;
  }
  if ((b0 & 0x01u) != 0) {
    if ((b0 & 0x80u) == 0) return false;
    out.kind = HeaderKind::kFastCommand;
    out.write = true;
    out.fast_command = static_cast<std::uint8_t>((b0 >> 1) & 0x1Fu);
    out.size = 1;
    return true;
  }
  out.kind = HeaderKind::kShort;
  out.write = (b0 & 0x80u) != 0;
  out.addr.file = static_cast<std::uint8_t>((b0 >> 1) & 0x1Fu);
  out.addr.offset = 0;
  out.size = 1;
  return true;
}

std::uint8_t crc8(std::span<const std::uint8_t> bytes, std::uint8_t crc) noexcept {
  for (const std::uint8_t byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x80u) != 0 ? static_cast<std::uint8_t>((crc << 1) ^ 0x07u) : static_cast<std::uint8_t>(crc << 1);
    }
  }
  return crc;
}

}  // namespace rilo::dw3000
