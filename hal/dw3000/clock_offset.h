#pragma once
// Clock offset between the responder and us, as the ratio used by SS-TWR:
// positive when our clock is slower than the remote one. Two sources:
//  - CIA_DIAG_0 (0x0C:0x20) bits 12:0, signed, ratio = value / 2^26;
//  - the carrier integrator DRX_DIAG3 (0x06:0x29), 21-bit signed (3 bytes
//    little-endian, sign bit 20; NOT one byte), converted through Hz and a
//    channel-dependent ppm factor.
#include <cstdint>

namespace rilo::dw3000 {

enum class UwbChannel : std::uint8_t { k5 = 5, k9 = 9 };

/// Two's-complement value of the low `bits` bits of `raw` (higher bits ignored).
constexpr std::int32_t signExtend(std::uint32_t raw, int bits) {
  const std::uint32_t mask = (bits >= 32) ? 0xFFFF'FFFFu : ((1u << bits) - 1u);
  const std::uint32_t v = raw & mask;
  const std::uint32_t sign = 1u << (bits - 1);
  return static_cast<std::int32_t>(static_cast<std::int64_t>(v ^ sign) - static_cast<std::int64_t>(sign));
}

inline constexpr int kCiaDiag0Bits = 13;
inline constexpr double kCiaDiag0Scale = 1.0 / 67108864.0;  // 2^-26
inline constexpr int kCarrierIntegratorBits = 21;
/// Carrier integrator LSB in Hz: 998.4e6 / 2 / 1024 / 131072.
inline constexpr double kCarrierIntegratorHzPerLsb = 998.4e6 / 2.0 / 1024.0 / 131072.0;

/// ppm of clock offset per Hz of carrier offset on a channel (negative:
/// a positive carrier integrator means our clock is faster).
constexpr double ppmPerCarrierHz(UwbChannel channel) {
  return channel == UwbChannel::k9 ? -1e6 / 7987.2e6 : -1e6 / 6489.6e6;
}

/// Ratio from the raw CIA_DIAG_0 register value (bits above 12 ignored).
constexpr double clockOffsetFromCiaDiag0(std::uint32_t raw) {
  return signExtend(raw, kCiaDiag0Bits) * kCiaDiag0Scale;
}

/// Signed carrier integrator from the 3 raw DRX_DIAG3 bytes (little-endian).
constexpr std::int32_t carrierIntegratorFromBytes(std::uint8_t b0, std::uint8_t b1, std::uint8_t b2) {
  return signExtend(static_cast<std::uint32_t>(b0) | (static_cast<std::uint32_t>(b1) << 8) |
                        (static_cast<std::uint32_t>(b2) << 16),
                    kCarrierIntegratorBits);
}

/// Ratio from the signed carrier integrator on `channel`.
constexpr double clockOffsetFromCarrierIntegrator(std::int32_t carrier_integrator, UwbChannel channel) {
  return carrier_integrator * kCarrierIntegratorHzPerLsb * ppmPerCarrierHz(channel) * 1e-6;
}

}  // namespace rilo::dw3000
