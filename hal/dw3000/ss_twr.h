#pragma once
// Single-sided two-way ranging at the initiator:
//   Tround = RX_resp - TX_poll   (our clock)
//   Treply = TX_resp - RX_poll   (responder's clock, from the response payload)
//   tof    = (Tround - Treply * (1 - clock_offset_ratio)) / 2   (device units)
//   range  = tof * 15.65 ps * 299702547 m/s
// All four stamps are 40-bit and already antenna-delay corrected by the chips.
#include <cstdint>

namespace rilo::dw3000 {

struct TwrTimestamps {
  std::uint64_t poll_tx = 0;   ///< our TX_TIME of the poll (40 bit)
  std::uint64_t resp_rx = 0;   ///< our RX_TIME of the response (40 bit)
  std::uint64_t poll_rx = 0;   ///< responder's RX time of the poll (40 bit, its clock)
  std::uint64_t resp_tx = 0;   ///< responder's TX time of the response (40 bit, its clock)
};

struct TwrResult {
  std::int64_t round_units = 0;  ///< Tround (device units)
  std::int64_t reply_units = 0;  ///< Treply (device units, responder clock)
  double tof_units = 0.0;        ///< one-way time of flight (device units)
  double range_m = 0.0;
};

/// Range from the four stamps; `clock_offset_ratio` positive when our clock
/// is slower than the responder's (0 = uncorrected).
TwrResult computeSsTwr(const TwrTimestamps& stamps, double clock_offset_ratio) noexcept;

/// Range error left by an uncorrected relative clock offset `ratio` over a
/// reply time `reply_s`: about -c * Treply * ratio / 2 (m).
double uncorrectedOffsetErrorM(double reply_s, double clock_offset_ratio) noexcept;

/// Antenna-delay calibration: the change (device units) to add to BOTH our TX
/// and RX antenna delays to remove a measured mean range bias
/// (measured - true, m): raising both by one unit shortens the range by
/// c * 15.65 ps = 4.69 mm (half from each).
double antennaDelayCorrectionUnits(double range_bias_m) noexcept;

}  // namespace rilo::dw3000
