// The Initializer's position-only fix of the newest measurements
// (Initializer::provisionalFix): what a user sees within seconds of the
// start, while yaw, velocity and the IMU biases still wait for motion.
// The same multilateration (or TDoA fix) as step 1 of an attempt, on a
// trailing window instead of the window's start: provisional_fix_window_s,
// grown by half up to provisional_fix_max_window_s until it holds enough
// anchors and measurements (sparse ranging gets none: too few ranges in
// seconds for a walker's fix).
#include <algorithm>

#include "estimation/init/initializer.h"
#include "estimation/init/window_time.h"

namespace rilo {

using init_detail::rangeIndexFrom;
using init_detail::toNs;

void Initializer::updateProvisionalFix() {
  const InitializerParams& P = params_;
  if (P.provisional_fix_interval_s <= 0.0 || meas_.empty()) return;
  const std::int64_t t_end = meas_.back().t_ns;
  // One try per interval, whether the last one was published or refused:
  // a refused fix must not be retried at every sample.
  if (provisional_tried_ns_ && t_end - *provisional_tried_ns_ < toNs(P.provisional_fix_interval_s)) return;
  provisional_tried_ns_ = t_end;
  const std::size_t end = meas_.size();
  std::size_t f0 = end;
  for (double len = P.provisional_fix_window_s;; len = std::min(P.provisional_fix_max_window_s, 1.5 * len)) {
    f0 = rangeIndexFrom(meas_, t_end - toNs(len));
    if (enoughForFix(f0, end) || len >= P.provisional_fix_max_window_s || f0 == 0) break;
  }
  // Two-way ranges only: the TDoA fix's own consensus is not judged here.
  const bool ranges = std::any_of(meas_.begin() + static_cast<std::ptrdiff_t>(f0), meas_.end(),
                                  [](const Measurement& m) { return m.kind == Measurement::Kind::kRange; });
  if (!ranges || !enoughForFix(f0, end)) return;
  bool from_tdoa = false;
  // Each anchor's ranges count as one in its covariance (fixOf's anchors_once):
  // the multilateration weighs every range as an independent one, but an
  // anchor's ranges within the window share most of their error (an NLOS
  // excess persists for seconds as the wearer walks, docs/noise-models.md,
  // "Why the foreign height stays 0.6 m low", and so do the anchor's survey
  // and antenna-delay errors): the covariance grows by the inlier ranges per
  // anchor (10 at 40 Hz over 8 anchors and 2 s), the antennas' spread added
  // after. Counted alone the fixes claimed 0.05-0.08 m while off by 0.19-0.25
  // m (rms per axis; docs/accuracy.md, session 44).
  const TagFix fix = fixOf(f0, end, t_end, &from_tdoa, /*anchors_once=*/true);
  if (!fix.valid || !fix.cov_p_w.allFinite() || from_tdoa) return;
  constexpr int kSoundAnchors = 4;
  if (fix.anchors_used < kSoundAnchors ||
      fix.inliers < P.provisional_min_inlier_fraction * static_cast<double>(fix.ranges)) {
    return;
  }
  // The newest fix stands for the time of its newest measurement; a failed
  // one keeps the previous (which a caller ages by its own t_ns).
  provisional_ = ProvisionalFix{t_end, fix.p_w_tag, fix.cov_p_w, ++provisional_sequence_};
  const HeightBand& band = P.height_band;
  if (band.enabled) {
    // A second of ranges from anchors a few metres up leaves the height to
    // the band's soft edges (on the own office sims the fix sat at an edge,
    // 0.5 m off, claiming 0.1 m): the band's middle and its spread (uniform
    // over its width) say what is known.
    const double width_m = band.maxZ() - band.minZ();
    provisional_->p_w_tag.z() = band.midZ();
    provisional_->cov_p_w.row(2).setZero();
    provisional_->cov_p_w.col(2).setZero();
    provisional_->cov_p_w(2, 2) = width_m * width_m / 12.0 + band.sigma_m * band.sigma_m;
  }
}

}  // namespace rilo
