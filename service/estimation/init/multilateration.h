#pragma once
// Robust multilateration of the UWB tag from the ranges of a short window:
// the first position the initializer can get without knowing anything.
//
// Model: the tag moves at constant velocity over the window,
//   p(t) = p + v (t - t_fix),   range_j = |p(t_j) - a_j| + noise (+ NLOS excess >= 0),
// solved by Levenberg-Marquardt on the robust loss of range_loss.h
// (heavy tail for too-long ranges, Huber for too-short ones), a weak velocity
// prior and the height band. Starts: the anchor centroid at the band's middle
// height (or 1 m below the centroid without a band), then the mirror of each
// solution across the anchors' best-fit plane (near-coplanar anchors: the
// mirror solution fits the ranges too). The lowest cost wins; the height
// band breaks the mirror tie, and without it a second solution within
// `ambiguity_cost_gap` makes the fix invalid.
// Quality: inliers (|r| <= inlier_sigmas), distinct inlier anchors, inlier RMS,
// PDOP of the inlier anchors' directions (with the band's height information,
// whitened by the range sigma, when it is on) and the position sigma of the fit.
// The lever arm is ignored: this is the antenna's position.
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "estimation/measurements/height_band.h"
#include "estimation/noise/robust_loss.h"
#include "math/types.h"
#include "sensors/samples.h"

namespace rilo {

struct MultilaterationParams {
  double sigma_m = 0.15;                ///< LOS range std-dev (m)
  RobustLossPtr long_side_loss;         ///< loss of too-long ranges; null: the asymmetric range loss at sigma_m
  double short_side_huber_k = 3.0;      ///< Huber threshold of too-short ranges (sigmas)
  HeightBand band;                      ///< tag height band (soft)
  bool fit_velocity = true;             ///< fit p and v (else p only: a still tag or a very short window)
  double velocity_prior_sigma_m_s = 2.0;  ///< weak zero-mean prior on v (walking speeds), m/s
  int max_iterations = 30;
  int min_anchors = 4;                  ///< distinct inlier anchors needed (3 suffice with the height band)
  int min_ranges = 6;                   ///< ranges needed in the window
  double inlier_sigmas = 3.0;           ///< |r| <= this many sigmas is an inlier
  double max_rms_m = 0.5;               ///< inlier residual RMS above this: poor fix (m)
  double max_pdop = 10.0;               ///< PDOP of the inlier anchors (and the band) above this: poor geometry
  /// The band's height information counts in the PDOP (4+ anchors) only when
  /// the inlier anchors spread in two horizontal directions: the ratio of
  /// their horizontal spreads (minor / major axis std-dev) at least this. A
  /// corridor's line of anchors (0.15 m across 20 m: 0.01) gets none.
  double min_band_credit_spread_ratio = 0.2;
  double min_inlier_fraction = 0.5;
  double ambiguity_cost_gap = 2.0;      ///< a distinct second solution closer in cost than this is ambiguous

  /// Throws std::invalid_argument naming the field.
  void validate() const;
};

struct TagFix {
  bool valid = false;
  std::string message;       ///< quality summary, or why the fix is not valid
  std::int64_t t_ns = 0;     ///< fix time (the model's reference time)
  Vec3 p_w_tag = Vec3::Zero();  ///< antenna position at t_ns (m)
  Vec3 v_w = Vec3::Zero();      ///< velocity over the window (m/s)
  int anchors_heard = 0;     ///< distinct anchors in the window
  int anchors_used = 0;      ///< distinct anchors with at least one inlier
  int ranges = 0;
  int inliers = 0;
  double rms_m = std::numeric_limits<double>::infinity();     ///< inlier residual RMS (m)
  double pdop = std::numeric_limits<double>::infinity();      ///< of the inlier anchor directions
  double sigma_p_m = std::numeric_limits<double>::infinity(); ///< sqrt(trace) of the position covariance (m)
  /// Position covariance (m^2, world), widened by the inliers' residual scale
  /// where it exceeds the nominal sigma (the data are noisier than modelled);
  /// infinite diagonal when not determined.
  Mat3 cov_p_w = Mat3::Identity() * std::numeric_limits<double>::infinity();
  double cost = std::numeric_limits<double>::infinity();      ///< final robust cost (whitened, ~chi^2/2)
  double second_cost_gap = std::numeric_limits<double>::infinity();  ///< cost of the best distinct other solution minus cost
  bool mirror_ambiguous = false;
};

/// Fix at t_ns from `ranges` (ranges with an unknown anchor id or a non-finite
/// value are skipped). Never throws on data; see TagFix::valid / message.
TagFix multilaterate(std::span<const RangeSample> ranges, std::int64_t t_ns, const std::vector<Vec3>& p_w_anchors,
                     const MultilaterationParams& params);

}  // namespace rilo
