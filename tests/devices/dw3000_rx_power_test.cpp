// RX level and first-path power: the user manual's formulas against worked
// numbers, the register decoding, and the driver reading them with every
// good exchange (through the emulator's channel), a failed read keeping the
// range.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>

#include "hal/dw3000/rx_power.h"

namespace rilo::dw3000 {
namespace {

RxDiagnostics diagnostics(std::uint32_t c, std::uint32_t f1, std::uint32_t f2, std::uint32_t f3, std::uint32_t n,
                          std::uint8_t d) {
  RxDiagnostics diag;
  diag.cir_power = c;
  diag.fp_ampl1 = f1;
  diag.fp_ampl2 = f2;
  diag.fp_ampl3 = f3;
  diag.accumulation_count = n;
  diag.dgc_decision = d;
  return diag;
}

// Worked numbers for the DW3000 user manual v1.1 formulas (4.7.1, 4.7.2):
// the table Qorvo's DW3xxx driver pins its fixed-point RSL code to
// (utest/test_rsl.cc, "dataset computed on a spreadsheet", 0.1 dB), and a
// real-world first-path reading from the same file. The manual itself gives
// the formulas and constants but no numeric example.
TEST(RxPowerFromDiagnostics, MatchesWorkedExamplesOfTheUserManualFormula) {
  // RX level, 64 MHz PRF (A = 121.7): 10 log10(47 * 2^21 / 65^2) - 121.7.
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(47, 0, 0, 0, 65, 0), true).rssi_dbm, -78.0, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(32, 0, 0, 0, 65, 0), true).rssi_dbm, -79.7, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(13, 0, 0, 0, 65, 0), true).rssi_dbm, -83.6, 0.05);
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(2, 0, 0, 0, 65, 0), true).rssi_dbm, -91.7, 0.05);
  // One DGC step adds 6 dB.
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(13, 0, 0, 0, 65, 1), true).rssi_dbm, -77.6, 0.05);
  // 16 MHz PRF (A = 113.8).
  EXPECT_NEAR(rxPowerFromDiagnostics(diagnostics(2, 0, 0, 0, 65, 0), false).rssi_dbm, -83.83, 0.05);

  // First path: F = 0x26D9, 0x27EA, 0x159E (2 fractional bits), N = 63,
  // D = 3. Qorvo's case is an STS reception (A = 120.7): -67.04 dBm; the
  // Ipatov preamble we range on has A = 121.7, 1 dB lower.
  const RxPower fp = rxPowerFromDiagnostics(diagnostics(0, 0x26D9, 0x27EA, 0x159E, 0x3F, 3), true);
  EXPECT_NEAR(fp.fp_power_dbm, -67.04 - 1.0, 0.05);
  EXPECT_TRUE(std::isnan(fp.rssi_dbm));  // C = 0: no RX level, not -inf
}

TEST(RxPowerFromDiagnostics, ExactFormulaAndNoDiagnostics) {
  // C = 2^15, N = 128: 10 log10(2^15 * 2^21 / 2^14) - 121.7 = 10 log10(2^22) - 121.7.
  const RxPower p = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 0), true);
  EXPECT_NEAR(p.rssi_dbm, 10.0 * std::log10(4194304.0) - 121.7, 1e-9);
  // F carry 2 fractional bits: 1000 each, 3e6 / 16384.
  EXPECT_NEAR(p.fp_power_dbm, 10.0 * std::log10(3e6 / 16384.0) - 121.7, 1e-9);
  const RxPower prf16 = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 0), false);
  EXPECT_NEAR(prf16.rssi_dbm - p.rssi_dbm, 121.7 - 113.8, 1e-9);
  EXPECT_NEAR(prf16.fp_power_dbm - p.fp_power_dbm, 121.7 - 113.8, 1e-9);
  const RxPower dgc = rxPowerFromDiagnostics(diagnostics(1u << 15, 4000, 4000, 4000, 128, 7), true);
  EXPECT_NEAR(dgc.rssi_dbm - p.rssi_dbm, 42.0, 1e-9);
  EXPECT_NEAR(dgc.fp_power_dbm - p.fp_power_dbm, 42.0, 1e-9);
  // No diagnostics: NaN, not -inf.
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(1000, 1, 1, 1, 0, 0), true).rssi_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(1000, 1, 1, 1, 0, 0), true).fp_power_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(0, 0, 0, 0, 128, 0), true).rssi_dbm));
  EXPECT_TRUE(std::isnan(rxPowerFromDiagnostics(diagnostics(0, 0, 0, 0, 128, 0), true).fp_power_dbm));
}

TEST(DecodeRxDiagnostics, MasksEveryFieldAtItsOffset) {
  std::array<std::uint8_t, kIpDiagBlockBytes> block{};
  block.fill(0xFF);  // reserved bits and the diagnostics between F3 and N all set
  const auto put = [&block](std::size_t reg_offset, std::uint32_t v) {
    for (std::size_t i = 0; i < 4; ++i) {
      block[reg_offset - kIpDiagFirstOffset + i] = static_cast<std::uint8_t>((v >> (8 * i)) & 0xFFu);
    }
  };
  put(0x2C, 0xFFFE'0000u | 0x1'2345u);
  put(0x30, 0xFFC0'0000u | 0x3A'BCDEu);
  put(0x34, 0xFFC0'0000u | 0x00'0001u);
  put(0x38, 0xFFC0'0000u | 0x2F'0000u);
  put(0x58, 0xFFFF'F000u | 0x077u);
  const RxDiagnostics d = decodeRxDiagnostics(block, 0xDFFF'FFFFu);  // bits 30:28 = 5
  EXPECT_EQ(d.cir_power, 0x1'2345u);
  EXPECT_EQ(d.fp_ampl1, 0x3A'BCDEu);
  EXPECT_EQ(d.fp_ampl2, 0x1u);
  EXPECT_EQ(d.fp_ampl3, 0x2F'0000u);
  EXPECT_EQ(d.accumulation_count, 0x77u);
  EXPECT_EQ(d.dgc_decision, 5);
  EXPECT_EQ(decodeRxDiagnostics(block, 0).dgc_decision, 0);
}

}  // namespace
}  // namespace rilo::dw3000
