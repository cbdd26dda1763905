#include "hal/dw3000/rx_power.h"

#include <cmath>

namespace rilo::dw3000 {
namespace {

constexpr std::uint32_t kCirPowerMask = 0x1FFFF;
constexpr std::uint32_t kFirstPathMask = 0x3FFFFF;
constexpr std::uint32_t kAccumulationMask = 0xFFF;
constexpr int kDgcDecisionShift = 28;
constexpr std::uint32_t kDgcDecisionMask = 0x7;

std::uint32_t le32At(std::span<const std::uint8_t> bytes, std::size_t offset) {
  return static_cast<std::uint32_t>(bytes[offset]) | (static_cast<std::uint32_t>(bytes[offset + 1]) << 8) |
         (static_cast<std::uint32_t>(bytes[offset + 2]) << 16) | (static_cast<std::uint32_t>(bytes[offset + 3]) << 24);
}

}  // namespace

RxDiagnostics decodeRxDiagnostics(std::span<const std::uint8_t, kIpDiagBlockBytes> block,
                                  std::uint32_t dgc_dbg) noexcept {
  RxDiagnostics d;
  d.cir_power = le32At(block, 0x2C - kIpDiagFirstOffset) & kCirPowerMask;
  d.fp_ampl1 = le32At(block, 0x30 - kIpDiagFirstOffset) & kFirstPathMask;
  d.fp_ampl2 = le32At(block, 0x34 - kIpDiagFirstOffset) & kFirstPathMask;
  d.fp_ampl3 = le32At(block, 0x38 - kIpDiagFirstOffset) & kFirstPathMask;
  d.accumulation_count = le32At(block, 0x58 - kIpDiagFirstOffset) & kAccumulationMask;
  d.dgc_decision = static_cast<std::uint8_t>((dgc_dbg >> kDgcDecisionShift) & kDgcDecisionMask);
  return d;
}

RxPower rxPowerFromDiagnostics(const RxDiagnostics& d, bool prf64) noexcept {
  RxPower p;
  if (d.accumulation_count == 0) return p;
  const double n = static_cast<double>(d.accumulation_count);
  const double n2 = n * n;
  const double offset_db = 6.0 * static_cast<double>(d.dgc_decision) - rxPowerConstantDb(prf64);
  if (d.cir_power > 0) {
    p.rssi_dbm = 10.0 * std::log10(static_cast<double>(d.cir_power) * 2097152.0 / n2) + offset_db;  // 2^21
  }
  // F1..F3 carry 2 fractional bits.
  const double f1 = static_cast<double>(d.fp_ampl1) / 4.0;
  const double f2 = static_cast<double>(d.fp_ampl2) / 4.0;
  const double f3 = static_cast<double>(d.fp_ampl3) / 4.0;
  const double fp = f1 * f1 + f2 * f2 + f3 * f3;
  if (fp > 0.0) p.fp_power_dbm = 10.0 * std::log10(fp / n2) + offset_db;
  return p;
}

}  // namespace rilo::dw3000
