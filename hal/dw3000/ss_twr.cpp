#include "hal/dw3000/ss_twr.h"

#include "hal/dw3000/timestamp.h"

namespace rilo::dw3000 {

TwrResult computeSsTwr(const TwrTimestamps& stamps, double clock_offset_ratio) noexcept {
  TwrResult r;
  r.round_units = timestampDiff(stamps.resp_rx, stamps.poll_tx);
  r.reply_units = timestampDiff(stamps.resp_tx, stamps.poll_rx);
  // Treply is scaled into our clock before the subtraction: at 20 ppm and
  // 500 us the correction is 10 ns, i.e. 1.5 m of range.
  r.tof_units = (static_cast<double>(r.round_units) -
                 static_cast<double>(r.reply_units) * (1.0 - clock_offset_ratio)) / 2.0;
  r.range_m = r.tof_units * kMetersPerDeviceUnit;
  return r;
}

double uncorrectedOffsetErrorM(double reply_s, double clock_offset_ratio) noexcept {
  return -kSpeedOfLightAirMps * reply_s * clock_offset_ratio / 2.0;
}

double antennaDelayCorrectionUnits(double range_bias_m) noexcept {
  // A TX delay raised by d lowers our TX stamps' lead by d and an RX delay
  // raised by d lowers RX stamps by d: Tround shrinks by 2d, tof by d.
  return range_bias_m / kMetersPerDeviceUnit;
}

}  // namespace rilo::dw3000
