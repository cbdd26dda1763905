#include "estimation/measurements/range_repeats.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

/// Weight of the newest interval in the running mean: about the last ten.
constexpr double kMeanGain = 0.1;
/// The shortest interval counted (ns): k stays finite for ranges stamped alike.
constexpr std::int64_t kMinIntervalNs = 1'000'000;

}  // namespace

void RangeRepeatsParams::validate() const {
  if (!(error_correlation_s >= 0.0 && error_correlation_s <= 60.0)) {
    throw std::invalid_argument("RangeRepeatsParams: error_correlation_s must lie in [0, 60] s, got " +
                                std::to_string(error_correlation_s));
  }
}

RangeRepeats::RangeRepeats(std::size_t anchors, RangeRepeatsParams params)
    : pairs_(anchors * kTagsPerAnchor), window_ns_(0) {
  params.validate();
  window_ns_ = static_cast<std::int64_t>(std::llround(params.error_correlation_s * 1e9));
}

std::size_t RangeRepeats::find(std::uint32_t anchor, std::uint32_t tag) const noexcept {
  if (static_cast<std::size_t>(anchor) >= pairs_.size() / kTagsPerAnchor) return kNone;
  const std::size_t first = static_cast<std::size_t>(anchor) * kTagsPerAnchor;
  std::size_t free = kNone;
  for (std::size_t i = first; i < first + kTagsPerAnchor; ++i) {
    if (pairs_[i].heard && pairs_[i].tag == tag) return i;
    if (!pairs_[i].heard && free == kNone) free = i;
  }
  return free;
}

void RangeRepeats::add(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns) noexcept {
  if (!enabled()) return;
  const std::size_t i = find(anchor, tag);
  if (i == kNone) return;
  Pair* p = &pairs_[i];
  if (!p->heard) {
    *p = Pair{};
    p->tag = tag;
  } else {
    // An interval longer than the window says no more than the window: the
    // two ranges share nothing either way (and a pause must not hold k at 1
    // for long once ranging is back). Two at one time are a millisecond apart.
    const std::int64_t interval_ns =
        std::clamp<std::int64_t>(t_ns - p->last_t_ns, kMinIntervalNs, std::max(window_ns_, kMinIntervalNs));
    const auto interval = static_cast<double>(interval_ns);
    p->mean_interval_ns =
        p->mean_interval_ns > 0.0 ? p->mean_interval_ns + kMeanGain * (interval - p->mean_interval_ns) : interval;
  }
  p->heard = true;
  p->last_t_ns = t_ns;
}

double RangeRepeats::repeats(std::uint32_t anchor, std::uint32_t tag) const noexcept {
  const std::size_t i = enabled() ? find(anchor, tag) : kNone;
  if (i == kNone || !pairs_[i].heard || !(pairs_[i].mean_interval_ns > 0.0)) return 1.0;
  return std::max(1.0, static_cast<double>(window_ns_) / pairs_[i].mean_interval_ns);
}

void RangeRepeats::reset() noexcept { std::fill(pairs_.begin(), pairs_.end(), Pair{}); }

}  // namespace rilo
