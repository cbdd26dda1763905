#pragma once
// Learns, from the TDoA rows' own residuals, how much NLOS excess a packet
// carries for a given receive diagnostic gap (RX level minus first-path
// power, dB; tdoa_model.h), and tells the graph how much to take off a row.
//
// Why: a row is d_b - d_a, so a packet of anchor b through a wall adds its
// excess and one of anchor a takes it off. The gap says how deep in NLOS a
// packet is, and on the TDoA sims the excess grows with it (at the true
// poses of office seeds 1-6: +0.1 m at 4-5 dB, +0.3 m at 8-9 dB, +0.7 m at
// 13-14 dB, over packets below 3 dB). The asymmetric loss only knows that a
// flagged packet is long, not by how much; a shift per gap bin moves the row
// to where its LOS core belongs. How the excess grows is a property of the
// building and the receiver, so it is learnt on line, not assumed: where the
// gap says nothing about the excess, the table stays near zero.
//
// Model: residual r = measured - predicted of a row = f(g_b) - f(g_a) + noise,
// f piecewise constant in bins of bin_db from 0, f = 0 below los_gap_db (the
// gauge: packets there are LOS on any DW1000/DW3000 front end, APS006).
// Update per row (a clipped LMS step, Huber's psi: one multipath outlier
// moves a bin by at most clip_m / n, clip_m / window_rows once the bin has
// window_rows rows; a bin's first row sets it, by up to clip_m):
//   e = clamp(r - (f(g_b) - f(g_a)), -clip_m, clip_m)
//   f(g_b) += lambda_b e,  f(g_a) -= lambda_a e,  lambda = max(1 / n_bin, 1 / window_rows)
// A bin is used once min_rows rows reached it; NaN gaps (rows without
// diagnostics, UTIL imports) are neither learnt from nor corrected.
// Measured in docs/noise-models.md ("Learning the TDoA packets' NLOS excess"):
// it lowers the sliding window's error, and gaps that say nothing do not.
// Fixed storage; add() and correction() never allocate.
#include <array>
#include <cstdint>

namespace rilo {

struct TdoaGapExcessParams {
  bool enabled = true;
  double bin_db = 1.0;         ///< gap bin width (dB), > 0
  double los_gap_db = 3.0;     ///< packets below this gap carry no excess (dB), >= 0
  double clip_m = 0.5;         ///< largest step error one row contributes (m), > 0
  double window_rows = 200.0;  ///< forgetting: lambda >= 1 / window_rows per row of a bin, >= 1
  int min_rows = 50;           ///< rows a bin needs before it is used, >= 1

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

class TdoaGapExcess {
 public:
  static constexpr int kBins = 32;  ///< bins beyond the last are clamped to it

  explicit TdoaGapExcess(const TdoaGapExcessParams& params = {});

  /// One row's residual r = measured - predicted (m) with its packets' gaps
  /// (dB; a: the reference anchor's packet). NaN gaps or residual: ignored.
  void add(double gap_a_db, double gap_b_db, double residual_m) noexcept;
  /// f(g_b) - f(g_a) (m): what to take off the row's measured difference; 0
  /// for NaN gaps, bins below los_gap_db and bins still learning.
  double correction(double gap_a_db, double gap_b_db) const noexcept;
  /// The learnt excess of a packet with this gap (m); 0 where not used.
  double excess(double gap_db) const noexcept;
  /// Rows that reached the bin of this gap (0 for NaN and LOS gaps).
  std::int64_t rows(double gap_db) const noexcept;
  std::uint64_t rowsLearnt() const noexcept { return learnt_; }
  const TdoaGapExcessParams& params() const noexcept { return params_; }
  void reset() noexcept;

 private:
  /// The bin of a gap, or -1 for NaN and gaps below los_gap_db.
  int binOf(double gap_db) const noexcept;

  TdoaGapExcessParams params_;
  std::array<double, kBins> excess_m_{};
  std::array<std::int64_t, kBins> rows_{};
  std::uint64_t learnt_ = 0;
};

}  // namespace rilo
