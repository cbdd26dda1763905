#pragma once
// The height at which the wearer carries the tag, learnt on line (issue 36:
// "a carry height may be learnt online ... never defaulted to the value of
// any recording"). Ranges from anchors far away tell almost nothing about the
// tag's height, and what little they tell is mostly their unremoved NLOS
// excess (docs/noise-models.md, "What holds the height"); the tracker lets
// them speak to the height only in proportion to their vertical lever
// (RangeFactor::setVerticalWeight) and holds each state's height weakly
// towards this carry height instead. It starts at the height band's middle
// and moves towards the heights the tracker estimated where ranges did tell
// the height: the state's weighted vertical information (sum over its ranges
// of (w s / sigma)^2, s the sine of elevation, w the range's vertical
// weight) is the weight of its post-fit height, forgotten over `memory_s`
// (HeightBand::carry_memory_s) so that a posture held for minutes is
// learnt. Bounded to the band.
// Single-threaded; no allocation once its ring has grown to the states
// awaiting their post-fit (a few).
#include <cstdint>
#include <utility>

#include "estimation/measurements/growing_ring.h"
#include "estimation/measurements/height_band.h"

namespace rilo {

class CarryHeight {
 public:
  /// Starts at band.midZ() with the information of a sigma of a quarter of
  /// the band's width (its middle half holds the height at 1 sigma); learns
  /// only with `learn` (else the band's middle, always). Throws
  /// std::invalid_argument unless band.carry_memory_s > 0.
  CarryHeight(const HeightBand& band, bool learn);

  /// Height evidence of state `index` (the sum above; ignored when < 0 or not finite).
  void addEvidence(std::uint64_t index, double info);
  /// The tracker's estimate of state `index` right after its update: its tag
  /// height (m, world) weighs in with the evidence noted for it. Earlier
  /// states without a post-fit are dropped.
  void notePostFit(std::uint64_t index, std::int64_t t_ns, double z_tag_m);

  double heightM() const { return height_m_; }  ///< tag height (m, world)
  double evidence() const { return info_; }     ///< current weight of the learnt part (1/m^2)

 private:
  HeightBand band_;
  bool learn_;
  double prior_info_;        ///< 1/m^2
  double info_ = 0.0;        ///< sum of weights, faded
  double info_z_ = 0.0;      ///< sum of weight x height, faded
  double height_m_;
  std::int64_t last_t_ns_ = 0;
  bool have_time_ = false;
  detail::GrowingRing<std::pair<std::uint64_t, double>> pending_{16};
};

}  // namespace rilo
