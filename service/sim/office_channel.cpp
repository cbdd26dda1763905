#include "sim/office_channel.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

namespace rilo::sim {
namespace {

void require(bool ok, const std::string& field, const char* what) {
  if (!ok) throw std::invalid_argument("ChannelParams." + field + " " + what);
}

void validateMaterial(const MaterialRf& m, const char* name) {
  require(m.loss_db >= 0.0 && m.loss_db <= 60.0, std::string(name) + ".loss_db", "must be in [0, 60] dB");
  require(m.delay_m >= 0.0 && m.delay_m <= 5.0, std::string(name) + ".delay_m", "must be in [0, 5] m");
  require(m.tail_m >= 0.0 && m.tail_m <= 5.0, std::string(name) + ".tail_m", "must be in [0, 5] m");
}

}  // namespace

void validate(const ChannelParams& p) {
  require(std::isfinite(p.rssi_1m_dbm), "rssi_1m_dbm", "must be finite");
  require(p.path_loss_exponent >= 1.0 && p.path_loss_exponent <= 6.0, "path_loss_exponent", "must be in [1, 6]");
  require(std::isfinite(p.sensitivity_dbm) && p.sensitivity_dbm < p.rssi_1m_dbm, "sensitivity_dbm",
          "must be finite and below rssi_1m_dbm");
  require(p.shadowing_sigma_db >= 0.0 && p.shadowing_sigma_db <= 20.0, "shadowing_sigma_db", "must be in [0, 20] dB");
  validateMaterial(p.drywall, "drywall");
  validateMaterial(p.concrete, "concrete");
  validateMaterial(p.desk, "desk");
  validateMaterial(p.cabinet, "cabinet");
  validateMaterial(p.person, "person");
  validateMaterial(p.pillar, "pillar");
  validateMaterial(p.body, "body");
  require(p.nlos_severity >= 0.0 && p.nlos_severity <= 10.0, "nlos_severity", "must be in [0, 10]");
  require(p.nlos_max_excess_m > 0.0 && p.nlos_max_excess_m <= 100.0, "nlos_max_excess_m", "must be in (0, 100] m");
  require(p.nlos_tail_cap >= 1.0 && p.nlos_tail_cap <= 1e6, "nlos_tail_cap", "must be in [1, 1e6]");
  require(p.field_length_m > 0.05 && p.field_length_m <= 100.0, "field_length_m", "must be in (0.05, 100] m");
  require(p.body_shadow_azimuth_rad >= 0.0 && p.body_shadow_azimuth_rad <= std::numbers::pi, "body_shadow_azimuth_rad",
          "must be in [0, pi]");
  require(std::abs(p.body_shadow_max_elevation_rad) <= 0.5 * std::numbers::pi, "body_shadow_max_elevation_rad",
          "must be in [-pi/2, pi/2]");
}

OfficeChannel::OfficeChannel(OfficePlan plan, std::vector<Eigen::Vector3d> p_w_anchors, const Eigen::Vector3d& p_b_tag,
                             const ChannelParams& params, std::uint64_t seed)
    : plan_(std::move(plan)), anchors_(std::move(p_w_anchors)), p_b_tag_(p_b_tag), params_(params) {
  validate(params_);
  SimRng rng(seed);
  for (std::size_t a = 0; a < anchors_.size(); ++a) {
    excess_field_.emplace_back(rng, params_.field_length_m);
    shadow_field_.emplace_back(rng, 2.0 * params_.field_length_m);
  }
}

LinkState OfficeChannel::link(std::size_t anchor, const KinematicState& body) const {
  const ChannelParams& P = params_;
  const Eigen::Vector3d& p_anchor = anchors_.at(anchor);
  const Eigen::Vector3d p_tag = body.T_w_b.transformFrom(p_b_tag_);
  LinkState L;
  L.true_range_m = (p_anchor - p_tag).norm();
  L.obstruction = obstruction(plan_, p_tag, p_anchor);
  if (P.body_shadowing) {
    const Eigen::Vector3d d_b = body.T_w_b.R.transpose() * (p_anchor - p_tag);
    const double azimuth = std::atan2(d_b.y(), d_b.x());
    const double elevation = std::atan2(d_b.z(), d_b.head<2>().norm());
    L.body_shadowed = std::abs(azimuth) > P.body_shadow_azimuth_rad && elevation < P.body_shadow_max_elevation_rad;
  }
  const Obstruction& o = L.obstruction;
  double delay = 0.0, tail = 0.0;
  auto add = [&](int count, const MaterialRf& m) {
    L.loss_db += count * m.loss_db;
    delay += count * m.delay_m;
    tail += count * m.tail_m;
  };
  add(o.drywall, P.drywall);
  add(o.concrete, P.concrete);
  add(o.desks, P.desk);
  add(o.cabinets, P.cabinet);
  add(o.people, P.person);
  add(o.pillars, P.pillar);
  add(L.body_shadowed ? 1 : 0, P.body);
  L.los = o.lineOfSight() && !L.body_shadowed;

  L.rssi_mean_dbm = P.rssi_1m_dbm - 10.0 * P.path_loss_exponent * std::log10(std::max(L.true_range_m, 0.1)) -
                    L.loss_db + P.shadowing_sigma_db * shadow_field_[anchor](p_tag);
  if (!L.los) {
    // Half-Cauchy quantile of the field's (uniformized) value: median 1, heavy tail.
    const double u = std::min(normalCdf(excess_field_[anchor](p_tag)), 0.9999);
    const double x = std::min(P.nlos_tail_cap, std::tan(0.5 * std::numbers::pi * u));
    L.excess_m = std::min(P.nlos_max_excess_m, P.nlos_severity * (delay + tail * x));
  }
  return L;
}

}  // namespace rilo::sim
