#include "estimation/factors/ultrasonic_factor.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

void requireFinite(double v, const char* name) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("UltrasonicFactor: ") + name + " must be finite");
}
void requireFinite(const Vec3& v, const char* name) {
  if (!v.allFinite()) throw std::invalid_argument(std::string("UltrasonicFactor: ") + name + " must be finite");
}
void requirePositive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0)) {
    throw std::invalid_argument(std::string("UltrasonicFactor: ") + name + " must be positive and finite, got " +
                                std::to_string(v));
  }
}

}  // namespace

UltrasonicFactor::UltrasonicFactor(Key pose_key, Key anchor_key, double range_m, double sigma_range_m,
                                   const Vec3& p_b_us, std::optional<UltrasonicElevation> elevation,
                                   RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key, anchor_key}, offset, "UltrasonicFactor"), std::move(loss)),
      range_m_(range_m),
      sigma_range_m_(sigma_range_m),
      inv_sigma_range_(1.0 / sigma_range_m),
      p_b_us_(p_b_us),
      p_w_anchor_(Vec3::Zero()),
      elevation_(elevation),
      anchor_is_variable_(true),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  validate();
  if (pose_key == anchor_key) throw std::invalid_argument("UltrasonicFactor: pose_key and anchor_key must differ");
}

UltrasonicFactor::UltrasonicFactor(Key pose_key, const Vec3& p_w_anchor, double range_m, double sigma_range_m,
                                   const Vec3& p_b_us, std::optional<UltrasonicElevation> elevation,
                                   RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key}, offset, "UltrasonicFactor"), std::move(loss)),
      range_m_(range_m),
      sigma_range_m_(sigma_range_m),
      inv_sigma_range_(1.0 / sigma_range_m),
      p_b_us_(p_b_us),
      p_w_anchor_(p_w_anchor),
      elevation_(elevation),
      anchor_is_variable_(false),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  validate();
  requireFinite(p_w_anchor, "p_w_anchor");
}

void UltrasonicFactor::validate() const {
  requireFinite(range_m_, "range_m");
  requireFinite(dt_s_, "time offset");
  requirePositive(sigma_range_m_, "sigma_range_m");
  requireFinite(p_b_us_, "p_b_us");
  if (elevation_) {
    requireFinite(elevation_->delta_h_m, "elevation.delta_h_m");
    requirePositive(elevation_->sigma_h_m, "elevation.sigma_h_m");
    // The base class applies rho(|r|) to a 2-dim residual: the sign an
    // asymmetric loss needs is gone, so refuse instead of silently misweighting.
    if (loss() != nullptr && !loss()->isSymmetric()) {
      throw std::invalid_argument("UltrasonicFactor: loss '" + loss()->name() +
                                  "' is asymmetric; it needs a scalar residual, but an elevation row makes the "
                                  "residual 2-dim (use a symmetric loss or drop the elevation)");
    }
  }
}

Key UltrasonicFactor::anchorKey() const {
  if (!anchor_is_variable_) throw std::logic_error("UltrasonicFactor::anchorKey: the anchor is a constant");
  return keys()[1];
}

Vec3 UltrasonicFactor::anchorPosition(const Values& x) const {
  return anchor_is_variable_ ? x.vec3(keys()[1]) : p_w_anchor_;
}

Vec3 UltrasonicFactor::receiverPosition(const Values& x) const {
  Vec3 p_w_us = x.pose(keys()[0]).transformFrom(p_b_us_);
  if (has_offset_) p_w_us += dt_s_ * x.vec3(keys()[velocitySlot()]);
  return p_w_us;
}

double UltrasonicFactor::predictedRange(const Values& x) const { return (receiverPosition(x) - anchorPosition(x)).norm(); }

double UltrasonicFactor::predictedHeightDifference(const Values& x) const {
  return verticalNormal().dot(receiverPosition(x) - anchorPosition(x));
}

void UltrasonicFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Pose3& T_w_b = x.pose(keys()[0]);
  const Vec3& p_w_anchor = anchor_is_variable_ ? x.vec3(keys()[1]) : p_w_anchor_;
  const Vec3 d_w = receiverPosition(x) - p_w_anchor;
  const RangeAndDirection rd = rangeAndDirection(d_w);
  const Vec3 n_w = verticalNormal();
  const int rows = dim();

  r.resize(rows);
  r(0) = (range_m_ - rd.range_m) * inv_sigma_range_;
  double inv_sigma_h = 0.0;
  if (elevation_) {
    inv_sigma_h = 1.0 / elevation_->sigma_h_m;
    r(1) = (n_w.dot(d_w) - elevation_->delta_h_m) * inv_sigma_h;
  }
  if (H == nullptr) return;

  // Row 0: dr/dp_tag = -u^T/sigma_r; row 1: dr/dp_tag = n^T/sigma_h. dr/dA = -dr/dp_tag.
  JacobianBlock& J_r_pose = (*H)[0];
  J_r_pose.resize(rows, 6);
  J_r_pose.row(0) = tagPointGradientToPoseTangent(T_w_b.R, p_b_us_, -inv_sigma_range_ * rd.u_w);
  if (elevation_) J_r_pose.row(1) = tagPointGradientToPoseTangent(T_w_b.R, p_b_us_, inv_sigma_h * n_w);
  if (anchor_is_variable_) {
    JacobianBlock& J_r_anchor = (*H)[1];
    J_r_anchor.resize(rows, 3);
    J_r_anchor.row(0) = inv_sigma_range_ * rd.u_w.transpose();
    if (elevation_) J_r_anchor.row(1) = -inv_sigma_h * n_w.transpose();
  }
  if (has_offset_) {
    JacobianBlock& J_r_velocity = (*H)[velocitySlot()];  // d p_w_us / d v_w = dt I
    J_r_velocity.resize(rows, 3);
    J_r_velocity.row(0) = (-dt_s_ * inv_sigma_range_) * rd.u_w.transpose();
    if (elevation_) J_r_velocity.row(1) = (dt_s_ * inv_sigma_h) * n_w.transpose();
  }
}

}  // namespace rilo
