#pragma once
// What the mixture said of an anchor's last ranges, as a stand-in NLOS
// indicator where the receiver reports no first-path power.
//
// A blocked path stays blocked for seconds while the wearer walks past the
// obstacle, but the asymmetric mixture judges each range alone: a range
// whose excess is below its decision point (2.1 sigma, 0.21 m shipped) is
// taken as LOS and pulls the estimate with its full weight. Without the
// receiver's first-path power the own office sims lose a third of their
// accuracy (docs/noise-models.md, session 42). So: when the anchor's last two
// ranges, both within window_s, sat beyond the decision point at the
// tracked pose after their update (the mixture took them as NLOS), the
// anchor's next range is taken as flagged NLOS (range_model.h: the NLOS
// component at its mode, never a gap bin's or the site's excess). One long range is
// the mixture's business; two in a row are a blocked path. A range that
// fits again clears it: the memory is the last two judgements, not a
// count. At ~1 Hz ranging an anchor is heard every few seconds, so the
// window never holds two and nothing changes there. A body with several
// antennas (tags.csv) keeps a memory per antenna and anchor: the body that
// blocks one antenna's path may leave the other's clear. The ranges are
// those the consistency monitor judged (range_consistency.h; with it
// disabled the memory is off); a flagged range is judged like any other,
// so a flagged anchor stays flagged only while its ranges stay long.
//
// With a receiver that reports the first-path power it is not used: its
// flag is better evidence, and the memory's extra flags cost 0.016 m on
// the held-out own sims (measured: docs/noise-models.md, session 42).
// Fixed storage, allocated at construction; nothing allocates per range.
#include <array>
#include <cstdint>
#include <vector>

namespace rilo {

struct NlosMemoryParams {
  /// Both judged ranges must be this recent (s; 0: off).
  double window_s = 0.5;

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

class NlosMemory {
 public:
  static constexpr int kRanges = 2;  ///< judged NLOS in a row before the next is flagged

  /// anchors: how many anchors (ids 0..anchors-1); decision_point_m: the
  /// residual (m) beyond which the mixture takes a range as NLOS (sigma x
  /// AsymmetricLoss::decisionPoint); NaN or +inf turns the memory off.
  NlosMemory(std::size_t anchors, double decision_point_m, NlosMemoryParams params);

  /// The residual (measured - predicted, m) of a range of `anchor` by the
  /// antenna `tag` (RangeSample::tag_id) taken at `t_ns`, judged at the
  /// tracked pose after its update.
  void judged(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns, double residual_m) noexcept;
  /// Whether a range of `anchor` by `tag` at `t_ns` should be taken as NLOS.
  bool remembersNlos(std::uint32_t anchor, std::uint32_t tag, std::int64_t t_ns) const noexcept;
  bool enabled() const noexcept { return window_ns_ > 0; }
  /// Tracking (re)started: forget everything.
  void reset() noexcept;

 private:
  /// Judgements kept per anchor, of all its antennas: two antennas
  /// interleaved still leave each its last two.
  static constexpr int kKept = 8;
  struct Judgement {
    std::int64_t t_ns = 0;
    std::uint32_t tag = 0;
    bool nlos = false;
  };
  struct Anchor {
    std::array<Judgement, kKept> ring{};
    int next = 0;    ///< slot the next judgement goes to
    int filled = 0;  ///< judgements held, at most kKept
  };
  std::vector<Anchor> anchors_;
  double decision_point_m_;
  std::int64_t window_ns_ = 0;
};

}  // namespace rilo
