#pragma once
// UWB radio channel between the tag on a walking person and the anchors of an
// office (sim/office.h): received power and the NLOS range excess of each
// link, as functions of the geometry.
//
// Model (one link = tag antenna <-> anchor):
//  - Received power: log-distance path loss, minus the loss of every wall,
//    box and (optionally) the wearer's own body on the direct path, plus slow
//    shadowing that varies smoothly with the tag position (a random field
//    with correlation length field_length_m). Fast fading is added by the
//    ranging model per packet, not here.
//  - NLOS: the link is NLOS whenever the direct path is obstructed (a wall,
//    furniture, a person or the body). Its range excess is
//        severity * (sum delay_k + (sum tail_k) * X),
//    summed over the obstructions k crossed, X a half-Cauchy variate with
//    median 1 produced by a smooth random field of the tag position (X =
//    tan(pi/2 Phi(G(p))), G unit Gaussian field), X at most nlos_tail_cap,
//    the excess at most nlos_max_excess_m.
//    So the excess grows with the number and kind of walls, has a heavy tail,
//    and persists for as long as the geometry does (seconds while walking
//    behind a wall, indefinitely while standing), rather than being drawn
//    afresh per range.
// Deterministic given the seed; no state changes on evaluation (thread-safe).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "sim/office.h"
#include "sim/office_random.h"
#include "sim/trajectory.h"

namespace rilo::sim {

/// Effect of one obstruction on the direct path.
struct MaterialRf {
  double loss_db = 0.0;  ///< attenuation of the direct path (dB)
  double delay_m = 0.0;  ///< deterministic range excess (m)
  double tail_m = 0.0;   ///< scale (median) of the heavy-tailed range excess (m)
};

struct ChannelParams {
  double rssi_1m_dbm = -62.0;        ///< LOS received level at 1 m (DW3000, channel 5, order of magnitude)
  double path_loss_exponent = 2.0;
  double sensitivity_dbm = -95.0;    ///< weaker links are not heard (no range)
  double shadowing_sigma_db = 2.0;   ///< slow shadowing, spatially correlated
  MaterialRf drywall{4.0, 0.04, 0.12};
  MaterialRf concrete{12.0, 0.15, 0.45};
  MaterialRf desk{1.5, 0.02, 0.05};
  MaterialRf cabinet{10.0, 0.20, 0.40};  ///< metal
  MaterialRf person{6.0, 0.10, 0.15};
  MaterialRf pillar{12.0, 0.15, 0.45};   ///< concrete pillar of a hall, floor to ceiling
  MaterialRf body{8.0, 0.08, 0.10};      ///< the wearer's own body (body shadowing)
  double nlos_severity = 1.0;        ///< scales the NLOS range excess (delay and tail); 0 = attenuation only
  double nlos_max_excess_m = 8.0;    ///< physical cap on the excess (m)
  double nlos_tail_cap = 25.0;       ///< cap on the half-Cauchy variate X (so a drywall alone stays below ~3 m)
  double field_length_m = 1.5;       ///< correlation length of excess and shadowing along the walk (m)
  bool body_shadowing = true;        ///< the wearer's body blocks anchors behind them
  double body_shadow_azimuth_rad = 1.92;        ///< anchor more than this off straight ahead (body x) is behind (110 deg)
  double body_shadow_max_elevation_rad = 0.7;   ///< paths steeper than this pass over the shoulder (40 deg)
};

/// Validates `p` (std::invalid_argument naming the field).
void validate(const ChannelParams& p);

struct LinkState {
  double true_range_m = 0.0;   ///< |tag antenna - anchor| (m)
  Obstruction obstruction;     ///< walls and boxes on the direct path
  bool body_shadowed = false;
  bool los = true;             ///< nothing obstructs the direct path (ground truth)
  double loss_db = 0.0;        ///< attenuation of the obstructions (dB)
  double rssi_mean_dbm = 0.0;  ///< path loss, obstructions and shadowing; no fast fading
  double excess_m = 0.0;       ///< NLOS range excess (0 when LOS)
};

/// The receiver's NLOS indicator for a packet over link L: RX level minus
/// first-path power (dB; the DW1000/DW3000 diagnostics). Small under LOS
/// (~2 dB), growing with the obstruction loss and the excess under NLOS.
/// unit_normal: one standard normal draw of the caller's stream.
inline double firstPathGapDb(const LinkState& L, double unit_normal) {
  return L.los ? 1.5 + std::abs(unit_normal)
               : 1.5 + 0.6 * L.loss_db + 2.5 * std::min(L.excess_m, 4.0) + 2.0 * std::abs(unit_normal);
}

class OfficeChannel {
 public:
  OfficeChannel(OfficePlan plan, std::vector<Eigen::Vector3d> p_w_anchors, const Eigen::Vector3d& p_b_tag,
                const ChannelParams& params, std::uint64_t seed);

  /// The link of anchor `anchor` with the tag of a body in state `body`.
  LinkState link(std::size_t anchor, const KinematicState& body) const;

  std::size_t anchorCount() const { return anchors_.size(); }
  const ChannelParams& params() const { return params_; }
  const OfficePlan& plan() const { return plan_; }

 private:
  OfficePlan plan_;
  std::vector<Eigen::Vector3d> anchors_;
  Eigen::Vector3d p_b_tag_;
  ChannelParams params_;
  std::vector<SmoothField> excess_field_, shadow_field_;  ///< per anchor
};

}  // namespace rilo::sim
