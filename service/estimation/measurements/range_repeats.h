#pragma once
// How many of an anchor's two-way ranges share one error, so that together
// they count as one measurement.
//
// A range's error need not be white at the rate a tag ranges: an NLOS
// excess persists while the wearer walks past the obstacle, and the anchor's
// survey and antenna-delay errors, and the multipath near the body, change
// only as the tag moves on (our sims: the error correlates 0.6-0.8 between
// an anchor's ranges 0.2 s apart; the foreign ones 0.15-0.25). The factor
// graph takes each range as independent, so at 40 Hz over 8 anchors an
// anchor's five ranges a second each count as a fresh look: where the errors
// persist the smoother trusts the ranges five times too much against the
// IMU, follows their common error, and publishes a covariance that keeps
// 44-70 % of the horizontal error inside its 95 % ellipse
// (docs/noise-models.md, session 44). Here each range of an anchor and antenna
// gets the weight 1 / k, with k the anchor's ranges within
// error_correlation_s: the rate at which that antenna ranges that anchor
// (a running mean of the intervals, each counted at most as the time) times
// the time. An anchor heard no more often than that (~1 Hz ranging over a
// few anchors, for a time of a second or two) keeps k = 1: nothing changes.
//
// Fixed storage, allocated at construction; nothing allocates per range.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace rilo {

struct RangeRepeatsParams {
  /// Over this time an anchor's range error stays what it was (s; 0: off,
  /// every range counts alone). Off by default: at 1 s (about the time a
  /// walker takes to move a metre) the own sims gain a quarter and the
  /// foreign offices, whose errors are nearly white, lose 8 %
  /// (docs/noise-models.md, session 44); the time should be learnt from the
  /// data before it is on.
  double error_correlation_s = 0.0;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

class RangeRepeats {
 public:
  /// Antennas followed per anchor; a further antenna's ranges count alone.
  static constexpr std::size_t kTagsPerAnchor = 4;

  /// anchors: ids 0..anchors-1 (a range of another id counts alone).
  RangeRepeats(std::size_t anchors, RangeRepeatsParams params);

  /// A range of `anchor` by the antenna `tag` (RangeSample::tag_id) at t_ns
  /// (non-decreasing per pair).
  void add(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns) noexcept;
  /// k >= 1: the ranges of the pair that share one error at its current rate.
  double repeats(std::uint32_t anchor, std::uint32_t tag) const noexcept;
  bool enabled() const noexcept { return window_ns_ > 0; }
  void reset() noexcept;

 private:
  struct Pair {
    std::uint32_t tag = 0;
    bool heard = false;             ///< the slot is in use (by `tag`)
    std::int64_t last_t_ns = 0;
    double mean_interval_ns = 0.0;  ///< 0: fewer than two ranges yet
  };
  static constexpr std::size_t kNone = static_cast<std::size_t>(-1);
  /// The pair's slot, else the anchor's first free one; kNone when the
  /// anchor is unknown or its slots are taken by other antennas.
  std::size_t find(std::uint32_t anchor, std::uint32_t tag) const noexcept;
  std::vector<Pair> pairs_;  ///< kTagsPerAnchor per anchor
  std::int64_t window_ns_;
};

}  // namespace rilo
