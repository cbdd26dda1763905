#pragma once
// One ranging measurement of any kind, as the graph stream buffers it: a UWB
// two-way range, a UWB TDoA range difference, or an ultrasonic range. Plain
// and fixed size (no heap), so the stream's ring never allocates per sample.
#include <cstdint>
#include <limits>

#include "sensors/samples.h"

namespace rilo {

struct Measurement {
  enum class Kind : std::uint8_t { kRange, kTdoa, kUltrasonic };
  Kind kind = Kind::kRange;
  std::int64_t t_ns = 0;
  std::uint32_t anchor = 0;    ///< range, ultrasonic: the anchor; TDoA: the reference anchor a
  std::uint32_t anchor_b = 0;  ///< TDoA: anchor b (diff = |p - A_b| - |p - A_a|); unused otherwise
  double value_m = 0.0;        ///< range, range difference or ultrasonic range (m)
  /// Range: the receiver's NLOS indicator, RX level minus first-path power
  /// (dB; RangeNoiseParams::nlos_power_gap_db); TDoA: that of anchor a's
  /// packet. NaN when not reported.
  double power_gap_db = std::numeric_limits<double>::quiet_NaN();
  double power_gap_b_db = std::numeric_limits<double>::quiet_NaN();  ///< TDoA: anchor b's packet's (dB)
  std::uint32_t tag = 0;       ///< range: the antenna on the body that measured it (RangeSample::tag_id)
  bool gap_from_rx_level = false;  ///< range: power_gap_db stands in from the RX level (RangeSample::fp_from_rx_level)
  bool nlos_from_memory = false;   ///< range: flagged by the anchor's last judged ranges (RangeSample::nlos_from_memory)

  static Measurement of(const RangeSample& s) {
    return {Kind::kRange,
            s.t_ns,
            s.anchor_id,
            0,
            s.range_m,
            s.rssi_dbm - s.fp_power_dbm,
            std::numeric_limits<double>::quiet_NaN(),
            s.tag_id,
            s.fp_from_rx_level,
            s.nlos_from_memory};
  }
  static Measurement of(const TdoaSample& s) {
    return {Kind::kTdoa, s.t_ns, s.anchor_a, s.anchor_b, s.diff_m, s.rssi_a_dbm - s.fp_power_a_dbm,
            s.rssi_b_dbm - s.fp_power_b_dbm};
  }
  static Measurement of(const UltrasonicSample& s) { return {Kind::kUltrasonic, s.t_ns, s.anchor_id, 0, s.range_m}; }
};

const char* toString(Measurement::Kind kind);

}  // namespace rilo
