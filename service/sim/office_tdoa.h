#pragma once
// Simulated UWB TDoA in the office (IMU-Ultrasonic-UWB paper: the tag only listens).
//
// Scheme (TDoA3-like, on a TDMA schedule as in TDoA2):
//  - The UWB anchors of the office transmit in turn, anchor k at
//        t = r / round_rate_hz + k / (round_rate_hz * N)      (round r, N anchors),
//    so every anchor transmits round_rate_hz times a second and the tag sees
//    round_rate_hz * N packets a second (20 Hz x 8 anchors = 160 by default).
//  - The tag hears a packet when the link's mean RSSI (office_channel.h) plus
//    fast fading (hearing_fading_db) reaches the sensitivity, and receives a
//    heard packet with probability packet_reception.
//  - A received packet of anchor b is paired with the most recent received
//    packet of another anchor a, at most max_reference_age_s old (one round
//    by default), whose anchor b also hears (anchor-to-anchor level from path
//    loss and the walls between them: the anchors timestamp each other's
//    packets for their clock offsets, as in TDoA3). That gives one row
//        diff_m = |p - A_b| - |p - A_a| + error,   t_ns = time of b's packet,
//    p the tag antenna at t (the tag's motion between the two packets, a
//    few cm at most within one round, is not modelled: the clock-corrected
//    difference is taken as one instant's).
//  - error = excess_b - excess_a (each path's NLOS excess from the office
//    channel: walls, furniture, people, the wearer's body, persistent over
//    seconds) + bias_b - bias_a (per-anchor antenna-delay residuals) + noise
//    (sigma_m, times nlos_noise_factor if either path is NLOS) + rarely a
//    large multipath error on one path (long, sometimes early), which enters
//    with + on b's path and - on a's. So a blocked anchor_b makes the
//    difference longer, a blocked reference shorter.
//  - Each row carries the tag's receive diagnostics of both packets, RX level
//    and first-path power (firstPathGapDb, as the SS-TWR ranges'), the
//    reference's as it was received: what a DW1000/DW3000 TDoA tag reads out
//    of every packet and what the estimator's NLOS indicator works on.
//  - los = 1 only if both paths are LOS (ground truth).
// Anchor clock drift and the anchors' own NLOS to each other are not
// modelled beyond audibility. Random draws come from their own stream of the
// seed (office_random.h), so the IMU and SS-TWR samples do not change.
#include <cstdint>
#include <memory>
#include <vector>

#include "sensors/samples.h"
#include "sim/office_scenario.h"

namespace rilo::sim {

/// Truth about one simulated TDoA measurement (evaluation and tests only).
struct TdoaTruth {
  double true_diff_m = 0.0;   ///< |p - A_b| - |p - A_a| at t (m)
  double error_m = 0.0;       ///< diff_m - true_diff_m (m)
  double excess_a_m = 0.0;    ///< NLOS excess of the reference path (m)
  double excess_b_m = 0.0;
  double bias_m = 0.0;        ///< bias_b - bias_a (m)
  bool los_a = true;
  bool los_b = true;
  bool outlier = false;
  bool outlier_on_b = false;  ///< which path the outlier hit
  double reference_age_s = 0.0;  ///< t - time of the reference packet (s)
};

/// TDoA measurements one at a time, in time order.
class OfficeTdoaStream {
 public:
  /// Uses p.tdoa (whether enabled or not), p.seed, p.duration_s, p.t0_ns and
  /// the channel's sensitivity and materials; the anchors are setup's.
  OfficeTdoaStream(const OfficeScenarioParams& p, const OfficeSetup& setup);
  /// Next measurement and its truth; false at the end of the session.
  bool next(TdoaSample& sample, TdoaTruth& truth);
  /// Counters so far (duration_s is the session's).
  const TdoaStats& stats() const { return stats_; }
  /// Fraction of the session done, in [0, 1].
  double progress() const;
  /// True if anchor b hears anchor a (symmetric).
  bool anchorsHearEachOther(std::size_t a, std::size_t b) const { return audible_.at(a * anchors_ + b) != 0; }

 private:
  TdoaParams tp_;
  double duration_s_ = 0.0;
  std::int64_t t0_ns_ = 0;
  OfficeSetup setup_;
  std::size_t anchors_ = 0;
  SimRng rng_;
  SimRng diagnostics_rng_;  ///< the packets' first-path gaps
  std::vector<double> bias_m_;
  std::vector<char> audible_;      ///< anchors_ x anchors_
  std::vector<double> last_rx_s_;  ///< time of each anchor's last received packet (-inf: none)
  std::vector<double> last_rssi_dbm_, last_gap_db_;  ///< that packet's RX level and first-path gap
  std::size_t slot_ = 0;
  double t_s_ = 0.0;
  bool done_ = false;
  TdoaStats stats_;
};

/// Mean level (dBm) at which anchor b hears anchor a: log-distance path loss
/// and the walls and boxes between them (ChannelParams materials), no shadowing.
double anchorToAnchorRssiDbm(const OfficePlan& plan, const ChannelParams& channel, const Eigen::Vector3d& p_w_a,
                             const Eigen::Vector3d& p_w_b);

}  // namespace rilo::sim
