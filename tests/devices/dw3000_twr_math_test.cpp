#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>

#include "hal/dw3000/clock_offset.h"
#include "hal/dw3000/ss_twr.h"
#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {
namespace {

constexpr std::uint64_t kWrap = kTimestampModulus;

TEST(Dw3000Timestamp, DifferenceIsModulo2To40) {
  EXPECT_EQ(timestampDiff(100, 40), 60);
  EXPECT_EQ(timestampDiff(40, 100), -60);
  EXPECT_EQ(timestampDiff(5, kWrap - 10), 15);     // across the wrap
  EXPECT_EQ(timestampDiff(kWrap - 10, 5), -15);
  EXPECT_EQ(timestampDiff(0, kWrap - 1), 1);
  // Bits above 40 are ignored.
  EXPECT_EQ(timestampDiff((std::uint64_t{7} << 40) | 5, kWrap - 10), 15);
  // Half the wrap is the limit of what can be told apart.
  EXPECT_EQ(timestampDiff(kWrap / 2 - 1, 0), static_cast<std::int64_t>(kWrap / 2 - 1));
  EXPECT_EQ(timestampDiff(kWrap / 2, 0), -static_cast<std::int64_t>(kWrap / 2));
}

TEST(Dw3000Timestamp, AddWrapsAndBytesAreLittleEndian) {
  EXPECT_EQ(timestampAdd(kWrap - 10, 15), 5u);
  EXPECT_EQ(timestampAdd(5, -15), kWrap - 10);
  std::array<std::uint8_t, 5> bytes{};
  writeTimestamp40(0x12'3456'789Aull, bytes.data());
  EXPECT_EQ(bytes, (std::array<std::uint8_t, 5>{0x9A, 0x78, 0x56, 0x34, 0x12}));
  EXPECT_EQ(readTimestamp40(bytes.data()), 0x12'3456'789Aull);
}

TEST(Dw3000Timestamp, UnitsAndUwbMicroseconds) {
  EXPECT_NEAR(kDeviceTimeUnitS, 15.65e-12, 0.01e-12);
  EXPECT_NEAR(kWrap * kDeviceTimeUnitS, 17.2, 0.05);
  EXPECT_NEAR(kUwbMicrosecondS / kDeviceTimeUnitS, static_cast<double>(kDeviceUnitsPerUwbMicrosecond), 1e-6);
  EXPECT_EQ(uwbMicrosecondsFromUs(1.0256410256), 1u);
  EXPECT_EQ(uwbMicrosecondsFromUs(400.0), 390u);  // 400 * 499.2 / 512
}

TEST(Dw3000ClockOffset, CiaDiag0Is13BitSignedOver2To26) {
  EXPECT_EQ(signExtend(0x1FFF, 13), -1);
  EXPECT_EQ(signExtend(0x1000, 13), -4096);
  EXPECT_EQ(signExtend(0x0FFF, 13), 4095);
  EXPECT_EQ(signExtend(0xE000 | 0x0005, 13), 5);  // bits above 12 ignored
  EXPECT_DOUBLE_EQ(clockOffsetFromCiaDiag0(1342), 1342.0 / 67108864.0);
  EXPECT_NEAR(clockOffsetFromCiaDiag0(1342), 20e-6, 0.01e-6);
  EXPECT_NEAR(clockOffsetFromCiaDiag0(0x2000 - 1342), -20e-6, 0.01e-6);
}

TEST(Dw3000ClockOffset, CarrierIntegratorUsesAll21Bits) {
  // -34900 as 21-bit two's complement with reserved bits set above it.
  const std::uint32_t raw = (static_cast<std::uint32_t>(-34900) & 0x1FFFFFu) | (0x5u << 21);
  const auto b0 = static_cast<std::uint8_t>(raw & 0xFF);
  const auto b1 = static_cast<std::uint8_t>((raw >> 8) & 0xFF);
  const auto b2 = static_cast<std::uint8_t>((raw >> 16) & 0xFF);
  EXPECT_EQ(carrierIntegratorFromBytes(b0, b1, b2), -34900);
  // One byte (the bug of a public driver copy) gives a different, small number.
  EXPECT_NE(signExtend(b0, 8), -34900);
  EXPECT_EQ(carrierIntegratorFromBytes(0xFF, 0xFF, 0x0F), (1 << 20) - 1);
  EXPECT_EQ(carrierIntegratorFromBytes(0x00, 0x00, 0x10), -(1 << 20));
}

TEST(Dw3000ClockOffset, CarrierIntegratorSignAndChannelFactor) {
  // A positive integrator means our clock is faster: a negative ratio.
  const double hz = 1000.0 * kCarrierIntegratorHzPerLsb;
  EXPECT_NEAR(clockOffsetFromCarrierIntegrator(1000, UwbChannel::k5), -hz / 6489.6e6, 1e-15);
  EXPECT_NEAR(clockOffsetFromCarrierIntegrator(1000, UwbChannel::k9), -hz / 7987.2e6, 1e-15);
  EXPECT_NEAR(kCarrierIntegratorHzPerLsb, 3.7193, 1e-4);
  // 20 ppm on channel 5 is about -34900 LSB.
  EXPECT_NEAR(clockOffsetFromCarrierIntegrator(-34900, UwbChannel::k5), 20e-6, 0.01e-6);
}

/// Stamps of an exchange with `tof_s`, `reply_s`, responder clock `e_r` and
/// ours `e_i`, our poll at `poll_tx`, its RX of the poll at `poll_rx`.
TwrTimestamps synthetic(double tof_s, double reply_s, double e_i, double e_r, std::uint64_t poll_tx,
                        std::uint64_t poll_rx) {
  const double f = kDeviceClockHz;
  TwrTimestamps s;
  s.poll_tx = poll_tx & kTimestampMask;
  s.poll_rx = poll_rx & kTimestampMask;
  const auto reply_units = static_cast<std::int64_t>(std::llround(reply_s * f * (1 + e_r)));
  const auto round_units = static_cast<std::int64_t>(std::llround((2 * tof_s + reply_s) * f * (1 + e_i)));
  s.resp_tx = timestampAdd(s.poll_rx, reply_units);
  s.resp_rx = timestampAdd(s.poll_tx, round_units);
  return s;
}

TEST(Dw3000SsTwr, RecoversTimeOfFlightWithClockOffset) {
  const double tof_s = 10.0 / kSpeedOfLightAirMps;  // 10 m
  const double e_i = 3e-6;
  const double e_r = 20e-6;
  const double ratio = 1.0 - (1.0 + e_i) / (1.0 + e_r);
  const TwrTimestamps s = synthetic(tof_s, 500e-6, e_i, e_r, 123'456'789, 987'654'321);
  const TwrResult r = computeSsTwr(s, ratio);
  // tof in our units is tof * F * (1 + e_i): 3 ppm of 10 m is 30 um.
  EXPECT_NEAR(r.range_m, 10.0, 1e-3);
  EXPECT_GT(r.round_units, r.reply_units);
  // Uncorrected, the error is -c * Treply * ratio / 2 (~ -1.27 m here).
  const TwrResult raw = computeSsTwr(s, 0.0);
  EXPECT_NEAR(raw.range_m - 10.0, uncorrectedOffsetErrorM(500e-6, ratio), 2e-3);
  EXPECT_NEAR(uncorrectedOffsetErrorM(650e-6, 1e-6), -0.0974, 1e-4);  // the notes' ~10 cm
}

TEST(Dw3000SsTwr, WrapsOfEitherClockDoNotMatter) {
  const double tof_s = 25.0 / kSpeedOfLightAirMps;
  const double e_r = -20e-6;
  const double ratio = 1.0 - 1.0 / (1.0 + e_r);
  for (const std::uint64_t poll_tx : {std::uint64_t{1000}, kWrap - 5'000'000, kWrap - 1}) {
    for (const std::uint64_t poll_rx : {std::uint64_t{77}, kWrap - 20'000'000, kWrap - 3}) {
      const TwrTimestamps s = synthetic(tof_s, 400e-6, 0.0, e_r, poll_tx, poll_rx);
      EXPECT_NEAR(computeSsTwr(s, ratio).range_m, 25.0, 1e-3) << poll_tx << " " << poll_rx;
    }
  }
}

TEST(Dw3000SsTwr, AntennaDelayCorrection) {
  EXPECT_NEAR(kMetersPerDeviceUnit, 4.69e-3, 0.01e-3);
  EXPECT_NEAR(antennaDelayCorrectionUnits(10 * kMetersPerDeviceUnit), 10.0, 1e-9);
  EXPECT_NEAR(antennaDelayCorrectionUnits(-0.5), -0.5 / kMetersPerDeviceUnit, 1e-9);
}

}  // namespace
}  // namespace rilo::dw3000
