#pragma once
// RX level and first-path power of the last reception, from the DW3000's CIA
// (Ipatov) diagnostics. DW3000 family user manual v1.1, sections 4.7.1
// "Estimating the signal power in the first path" and 4.7.2 "Estimating the
// receive signal power":
//   RX level = 10 log10(C * 2^21 / N^2) + 6 D - A
//   FP power = 10 log10((F1^2 + F2^2 + F3^2) / N^2) + 6 D - A
// with C the CIR power (IP_DIAG_1), F1..F3 the first-path amplitudes
// (IP_DIAG_2..4, 2 fractional bits), N the preamble accumulation count
// (IP_DIAG_12), D the DGC decision (DGC_DBG bits 30:28; 0 when DGC_CFG
// RX_TUNE_EN is off) and A = 121.7 dB at 64 MHz PRF, 113.8 dB at 16 MHz
// (Ipatov preamble; the DW1000's 121.74 / 113.77 are close but not these).
// The 2^21 is the C0 silicon's (DW3110 / DW3120, the parts we accept); the
// D0/E0 parts (DW3720) use 2^17.
//
// The difference RX level - FP power is the NLOS indicator (Decawave APS006:
// above ~6 dB the first path is likely attenuated or blocked).
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>

namespace rilo::dw3000 {

/// Raw diagnostic fields, masked to their widths.
struct RxDiagnostics {
  std::uint32_t cir_power = 0;           ///< C, IP_DIAG_1 bits 16:0
  std::uint32_t fp_ampl1 = 0;            ///< F1, IP_DIAG_2 bits 21:0 (2 fractional bits)
  std::uint32_t fp_ampl2 = 0;            ///< F2, IP_DIAG_3 bits 21:0
  std::uint32_t fp_ampl3 = 0;            ///< F3, IP_DIAG_4 bits 21:0
  std::uint32_t accumulation_count = 0;  ///< N, IP_DIAG_12 bits 11:0
  std::uint8_t dgc_decision = 0;         ///< D, 0..7 (0 without DGC)
};

struct RxPower {
  double rssi_dbm = std::numeric_limits<double>::quiet_NaN();      ///< RX level (dBm)
  double fp_power_dbm = std::numeric_limits<double>::quiet_NaN();  ///< first-path power (dBm)
};

/// Register window read in one burst: file 0x0C from IP_DIAG_1 (0x2C) up to
/// and including IP_DIAG_12 (0x58..0x5B).
inline constexpr std::uint8_t kIpDiagFirstOffset = 0x2C;
inline constexpr std::size_t kIpDiagBlockBytes = 0x5C - kIpDiagFirstOffset;

/// Fields of the IP_DIAG_1..IP_DIAG_12 burst (`block` holds
/// kIpDiagBlockBytes bytes from 0x0C:0x2C); reserved bits are masked off.
/// `dgc_dbg` is DGC_DBG (0x03:0x60) or 0 when DGC is off.
RxDiagnostics decodeRxDiagnostics(std::span<const std::uint8_t, kIpDiagBlockBytes> block,
                                  std::uint32_t dgc_dbg) noexcept;

/// The user manual's estimates; NaN fields when N is zero or the power term
/// is zero (no diagnostics), never -inf. `prf64`: preamble codes 9..24.
RxPower rxPowerFromDiagnostics(const RxDiagnostics& d, bool prf64) noexcept;

/// The constant A (dB) of the formulas.
constexpr double rxPowerConstantDb(bool prf64) noexcept { return prf64 ? 121.7 : 113.8; }

}  // namespace rilo::dw3000
