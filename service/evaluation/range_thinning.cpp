#include "evaluation/range_thinning.h"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace rilo {

RangeThinning rangeThinningFromName(const std::string& name) {
  if (name == "rotate") return RangeThinning::kRotate;
  if (name == "first") return RangeThinning::kFirst;
  throw std::invalid_argument("range thinning '" + name + "': expected rotate or first");
}

const char* rangeThinningName(RangeThinning mode) { return mode == RangeThinning::kRotate ? "rotate" : "first"; }

std::vector<RangeSample> thinRanges(const std::vector<RangeSample>& ranges, const RangeThinningOptions& options) {
  if (!(options.rate_hz >= 0.0) || !std::isfinite(options.rate_hz)) {
    throw std::invalid_argument("range thinning: rate_hz must be finite and >= 0");
  }
  if (options.cycle_ns <= 0) throw std::invalid_argument("range thinning: cycle_ns must be > 0");
  if (options.rate_hz == 0.0) return ranges;
  const auto interval_ns = static_cast<std::int64_t>(std::llround(1e9 / options.rate_hz));

  std::vector<RangeSample> kept;
  std::unordered_map<std::uint32_t, std::int64_t> last_kept_ns;  // by anchor
  std::int64_t slot_open_ns = std::numeric_limits<std::int64_t>::min();
  std::size_t i = 0;
  while (i < ranges.size()) {
    if (ranges[i].t_ns < slot_open_ns) {
      ++i;
      continue;
    }
    std::size_t pick = i, end = i + 1;
    if (options.mode == RangeThinning::kRotate) {
      auto ranged_at = [&](std::uint32_t anchor) {
        auto it = last_kept_ns.find(anchor);
        return it == last_kept_ns.end() ? std::numeric_limits<std::int64_t>::min() : it->second;
      };
      for (; end < ranges.size() && ranges[end].t_ns < ranges[i].t_ns + options.cycle_ns; ++end) {
        if (ranged_at(ranges[end].anchor_id) < ranged_at(ranges[pick].anchor_id)) pick = end;  // ties: earliest
      }
    }
    kept.push_back(ranges[pick]);
    last_kept_ns[ranges[pick].anchor_id] = ranges[pick].t_ns;
    slot_open_ns = ranges[pick].t_ns + interval_ns;
    i = pick + 1;
  }
  return kept;
}

}  // namespace rilo
