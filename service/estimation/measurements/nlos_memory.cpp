#include "estimation/measurements/nlos_memory.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

void NlosMemoryParams::validate() const {
  if (!(window_s >= 0.0 && window_s <= 60.0)) {
    throw std::invalid_argument("NlosMemoryParams.window_s must be in [0, 60] s (0 or below 1 ns: off), got " +
                                std::to_string(window_s));
  }
}

NlosMemory::NlosMemory(std::size_t anchors, double decision_point_m, NlosMemoryParams params)
    : anchors_(anchors), decision_point_m_(decision_point_m) {
  params.validate();
  if (decision_point_m <= 0.0) {  // NaN compares false: off, as +inf
    throw std::invalid_argument("NlosMemory: decision_point_m must be > 0 (m), or NaN or +inf (off), got " +
                                std::to_string(decision_point_m));
  }
  if (std::isfinite(decision_point_m)) window_ns_ = static_cast<std::int64_t>(std::llround(params.window_s * 1e9));
}

void NlosMemory::judged(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns, double residual_m) noexcept {
  if (!enabled() || anchor >= anchors_.size()) return;
  Anchor& a = anchors_[anchor];
  a.ring[static_cast<std::size_t>(a.next)] = Judgement{t_ns, tag, residual_m > decision_point_m_};
  a.next = (a.next + 1) % kKept;
  if (a.filled < kKept) ++a.filled;
}

bool NlosMemory::remembersNlos(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns) const noexcept {
  if (!enabled() || anchor >= anchors_.size()) return false;
  const Anchor& a = anchors_[anchor];
  int seen = 0;
  // Newest first: the antenna's last kRanges judgements must all be NLOS and recent.
  for (int k = 1; k <= a.filled && seen < kRanges; ++k) {
    const Judgement& j = a.ring[static_cast<std::size_t>((a.next - k + kKept) % kKept)];
    if (j.tag != tag) continue;
    if (!j.nlos || t_ns - j.t_ns > window_ns_) return false;
    ++seen;
  }
  return seen == kRanges;
}

void NlosMemory::reset() noexcept {
  for (Anchor& a : anchors_) a = Anchor{};
}

}  // namespace rilo
