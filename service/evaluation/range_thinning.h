#pragma once
// Lower ranging rates from a recording made at a high one (`--range-hz`, the
// Ranging-IMU Fusion paper's rate sweep, Fig. 7 / Table II).
//
// A tag that ranges at a low total rate picks whom to range with: our DW3000
// scheduler cycles through the anchors in range. Keeping simply the first
// range after each interval instead keeps whatever the recorded receiver
// reported first, and a receiver that reports the strongest anchor first then
// gives one anchor for many seconds: at 1 Hz on a simulated office, runs of 9
// and 16 ranges to the same anchor, which leave the position unobservable
// across that anchor's direction. kRotate emulates the scheduler: when a slot
// opens, it looks at the ranges of the next ranging cycle and keeps the one
// to the anchor ranged longest ago.
#include <cstdint>
#include <string>
#include <vector>

#include "sensors/samples.h"

namespace rilo {

enum class RangeThinning {
  kRotate,  ///< per slot, the anchor ranged longest ago among the next cycle's ranges (default)
  kFirst,   ///< per slot, the first range
};

/// "rotate" | "first"; throws std::invalid_argument otherwise.
RangeThinning rangeThinningFromName(const std::string& name);
const char* rangeThinningName(RangeThinning mode);

struct RangeThinningOptions {
  double rate_hz = 0.0;                     ///< kept ranges are at least 1 / rate_hz apart; 0 keeps all
  RangeThinning mode = RangeThinning::kRotate;
  std::int64_t cycle_ns = 100'000'000;      ///< kRotate: how far ahead a slot looks (one ranging cycle)
};

/// The ranges kept, in time order (`ranges` must be in time order). Throws
/// std::invalid_argument for a negative rate or a non-positive cycle.
std::vector<RangeSample> thinRanges(const std::vector<RangeSample>& ranges, const RangeThinningOptions& options);

}  // namespace rilo
