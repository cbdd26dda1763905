#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <string_view>

#include "hal/dw3000/registers.h"
#include "hal/dw3000/spi_framing.h"

namespace rilo::dw3000 {
namespace {

TEST(Dw3000Framing, ShortHeaderForOffsetZero) {
  const SpiHeader read_dev_id = encodeHeader(reg::kDevId, false);
  ASSERT_EQ(read_dev_id.size, 1u);
  EXPECT_EQ(read_dev_id.bytes[0], 0x00);
  const SpiHeader write_tx_buffer = encodeHeader(reg::kTxBuffer, true);
  ASSERT_EQ(write_tx_buffer.size, 1u);
  EXPECT_EQ(write_tx_buffer.bytes[0], 0x80 | (0x14 << 1));  // 0xA8
  const SpiHeader read_rx_buffer = encodeHeader(reg::kRxBuffer0, false);
  EXPECT_EQ(read_rx_buffer.bytes[0], 0x12 << 1);
}

TEST(Dw3000Framing, ExtendedHeaderCarriesOffsetAndMode) {
  // SYS_STATUS 0x00:0x44: offset bit 6 in byte 0 bit 0, bits 5..0 in byte 1 bits 7..2.
  const SpiHeader read_status = encodeHeader(reg::kSysStatus, false);
  ASSERT_EQ(read_status.size, 2u);
  EXPECT_EQ(read_status.bytes[0], 0x41);
  EXPECT_EQ(read_status.bytes[1], 0x10);
  const SpiHeader write_status = encodeHeader(reg::kSysStatus, true);
  EXPECT_EQ(write_status.bytes[0], 0xC1);
  EXPECT_EQ(write_status.bytes[1], 0x10);
  // CIA_DIAG_0 0x0C:0x20 read: 0x40 | 0x0C << 1, offset 0x20 << 2.
  const SpiHeader cia = encodeHeader(reg::kCiaDiag0, false);
  EXPECT_EQ(cia.bytes[0], 0x58);
  EXPECT_EQ(cia.bytes[1], 0x80);
  // Masked writes use the extended form even at offset 0; mode in bits 1..0.
  const SpiHeader masked8 = encodeHeader(reg::kCiaConf, true, AccessMode::kMask8);
  ASSERT_EQ(masked8.size, 2u);
  EXPECT_EQ(masked8.bytes[0], 0x80 | 0x40 | (0x0E << 1));
  EXPECT_EQ(masked8.bytes[1], 0x01);
  EXPECT_EQ(encodeHeader(reg::kTxFctrl, true, AccessMode::kMask16).bytes[1], (0x24 << 2) | 0x02);
  EXPECT_EQ(encodeHeader(reg::kAckResp, true, AccessMode::kMask32).bytes[1], (0x08 << 2) | 0x03);
  EXPECT_EQ(maskedBodySize(AccessMode::kMask8), 2u);
  EXPECT_EQ(maskedBodySize(AccessMode::kMask16), 4u);
  EXPECT_EQ(maskedBodySize(AccessMode::kMask32), 8u);
  EXPECT_EQ(maskedBodySize(AccessMode::kPlain), 0u);
}

TEST(Dw3000Framing, FastCommandsMatchTheNotes) {
  EXPECT_EQ(encodeFastCommand(fast_cmd::kTxRxOff), 0x81);
  EXPECT_EQ(encodeFastCommand(fast_cmd::kTx), 0x83);
  EXPECT_EQ(encodeFastCommand(fast_cmd::kRx), 0x85);
  EXPECT_EQ(encodeFastCommand(fast_cmd::kTxW4r), 0x99);
  EXPECT_EQ(encodeFastCommand(fast_cmd::kDtxW4r), 0x9B);
  EXPECT_EQ(encodeFastCommand(fast_cmd::kClrIrqs), 0xA5);
}

TEST(Dw3000Framing, DecodeInvertsEncodeForEveryAddressAndMode) {
  for (int file = 0; file <= 0x1F; ++file) {
    for (int offset = 0; offset <= 0x7F; ++offset) {
      for (const bool write : {false, true}) {
        for (const AccessMode mode : {AccessMode::kPlain, AccessMode::kMask8, AccessMode::kMask16, AccessMode::kMask32}) {
          if (!write && mode != AccessMode::kPlain) continue;
          const RegAddr addr{static_cast<std::uint8_t>(file), static_cast<std::uint8_t>(offset)};
          const SpiHeader h = encodeHeader(addr, write, mode);
          DecodedHeader d;
          ASSERT_TRUE(decodeHeader(h.view(), d));
          EXPECT_EQ(d.size, h.size);
          EXPECT_EQ(d.kind, h.size == 1 ? HeaderKind::kShort : HeaderKind::kExtended);
          EXPECT_EQ(d.write, write);
          EXPECT_EQ(d.addr, addr) << file << ":" << offset;
          EXPECT_EQ(d.mode, mode);
        }
      }
    }
  }
  for (std::uint8_t cmd = 0; cmd <= 0x1F; ++cmd) {
    const std::array<std::uint8_t, 1> byte{encodeFastCommand(cmd)};
    DecodedHeader d;
    ASSERT_TRUE(decodeHeader(byte, d));
    EXPECT_EQ(d.kind, HeaderKind::kFastCommand);
    EXPECT_EQ(d.fast_command, cmd);
  }
}

TEST(Dw3000Framing, DecodeRejectsMalformedHeaders) {
  DecodedHeader d;
  EXPECT_FALSE(decodeHeader({}, d));
  const std::array<std::uint8_t, 1> half_extended{0x41};
  EXPECT_FALSE(decodeHeader(half_extended, d));
  const std::array<std::uint8_t, 1> read_with_bit0{0x01};  // b0 set without b7: no such header
  EXPECT_FALSE(decodeHeader(read_with_bit0, d));
}

TEST(Dw3000Framing, Crc8IsPolynomial07) {
  // CRC-8 (x^8 + x^2 + x + 1, init 0) check value of "123456789" is 0xF4.
  constexpr std::string_view check = "123456789";
  std::array<std::uint8_t, 9> bytes{};
  for (std::size_t i = 0; i < check.size(); ++i) bytes[i] = static_cast<std::uint8_t>(check[i]);
  EXPECT_EQ(crc8(bytes), 0xF4);
  // Chaining over header then body equals one pass.
  EXPECT_EQ(crc8(std::span<const std::uint8_t>(bytes).subspan(4), crc8(std::span<const std::uint8_t>(bytes).first(4))),
            0xF4);
  EXPECT_EQ(crc8({}), 0x00);
}

}  // namespace
}  // namespace rilo::dw3000
