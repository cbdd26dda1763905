#include "estimation/factors/tdoa_factor.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

void requireFinite(double v, const char* name) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("TdoaFactor: ") + name + " must be finite");
}
void requireFinite(const Vec3& v, const char* name) {
  if (!v.allFinite()) throw std::invalid_argument(std::string("TdoaFactor: ") + name + " must be finite");
}
void requirePositive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0)) {
    throw std::invalid_argument(std::string("TdoaFactor: ") + name + " must be positive and finite, got " +
                                std::to_string(v));
  }
}

}  // namespace

TdoaFactor::TdoaFactor(Key pose_key, Key anchor_a_key, Key anchor_b_key, double diff_m, double sigma_m,
                       const Vec3& p_b_tag, RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key, anchor_a_key, anchor_b_key}, offset, "TdoaFactor"), std::move(loss)),
      diff_m_(diff_m),
      sigma_m_(sigma_m),
      inv_sigma_(1.0 / sigma_m),
      p_b_tag_(p_b_tag),
      p_w_anchor_a_(Vec3::Zero()),
      p_w_anchor_b_(Vec3::Zero()),
      anchors_are_variables_(true),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  requireFinite(dt_s_, "time offset");
  requireFinite(diff_m, "diff_m");
  requirePositive(sigma_m, "sigma_m");
  requireFinite(p_b_tag, "p_b_tag");
  if (anchor_a_key == anchor_b_key) throw std::invalid_argument("TdoaFactor: anchor_a_key and anchor_b_key must differ");
  if (pose_key == anchor_a_key || pose_key == anchor_b_key) {
    throw std::invalid_argument("TdoaFactor: pose_key must differ from the anchor keys");
  }
}

TdoaFactor::TdoaFactor(Key pose_key, const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b, double diff_m,
                       double sigma_m, const Vec3& p_b_tag, RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key}, offset, "TdoaFactor"), std::move(loss)),
      diff_m_(diff_m),
      sigma_m_(sigma_m),
      inv_sigma_(1.0 / sigma_m),
      p_b_tag_(p_b_tag),
      p_w_anchor_a_(p_w_anchor_a),
      p_w_anchor_b_(p_w_anchor_b),
      anchors_are_variables_(false),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  requireFinite(dt_s_, "time offset");
  requireFinite(diff_m, "diff_m");
  requirePositive(sigma_m, "sigma_m");
  requireFinite(p_b_tag, "p_b_tag");
  requireFinite(p_w_anchor_a, "p_w_anchor_a");
  requireFinite(p_w_anchor_b, "p_w_anchor_b");
  if (p_w_anchor_a == p_w_anchor_b) {
    throw std::invalid_argument("TdoaFactor: p_w_anchor_a and p_w_anchor_b must differ");
  }
}

Key TdoaFactor::anchorAKey() const {
  if (!anchors_are_variables_) throw std::logic_error("TdoaFactor::anchorAKey: the anchors are constants");
  return keys()[1];
}

Key TdoaFactor::anchorBKey() const {
  if (!anchors_are_variables_) throw std::logic_error("TdoaFactor::anchorBKey: the anchors are constants");
  return keys()[2];
}

Vec3 TdoaFactor::anchorAPosition(const Values& x) const {
  return anchors_are_variables_ ? x.vec3(keys()[1]) : p_w_anchor_a_;
}

Vec3 TdoaFactor::anchorBPosition(const Values& x) const {
  return anchors_are_variables_ ? x.vec3(keys()[2]) : p_w_anchor_b_;
}

Vec3 TdoaFactor::tagPosition(const Values& x) const {
  Vec3 p_w_tag = x.pose(keys()[0]).transformFrom(p_b_tag_);
  if (has_offset_) p_w_tag += dt_s_ * x.vec3(keys()[velocitySlot()]);
  return p_w_tag;
}

double TdoaFactor::predictedDifference(const Values& x) const {
  const Vec3 p_w_tag = tagPosition(x);
  return (p_w_tag - anchorBPosition(x)).norm() - (p_w_tag - anchorAPosition(x)).norm();
}

void TdoaFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Pose3& T_w_b = x.pose(keys()[0]);
  const Vec3& p_w_a = anchors_are_variables_ ? x.vec3(keys()[1]) : p_w_anchor_a_;
  const Vec3& p_w_b = anchors_are_variables_ ? x.vec3(keys()[2]) : p_w_anchor_b_;
  const Vec3 p_w_tag = tagPosition(x);
  const RangeAndDirection to_a = rangeAndDirection(p_w_tag - p_w_a);
  const RangeAndDirection to_b = rangeAndDirection(p_w_tag - p_w_b);

  r.resize(1);
  r(0) = (diff_m_ - (to_b.range_m - to_a.range_m)) * inv_sigma_;
  if (H == nullptr) return;

  // dh/dp_tag = u_b^T - u_a^T; dh/dA_a = u_a^T; dh/dA_b = -u_b^T; r = (z - h)/sigma.
  JacobianBlock& J_r_pose = (*H)[0];
  J_r_pose.resize(1, 6);
  J_r_pose = tagPointGradientToPoseTangent(T_w_b.R, p_b_tag_, inv_sigma_ * (to_a.u_w - to_b.u_w));
  if (anchors_are_variables_) {
    JacobianBlock& J_r_anchor_a = (*H)[1];
    J_r_anchor_a.resize(1, 3);
    J_r_anchor_a = -inv_sigma_ * to_a.u_w.transpose();
    JacobianBlock& J_r_anchor_b = (*H)[2];
    J_r_anchor_b.resize(1, 3);
    J_r_anchor_b = inv_sigma_ * to_b.u_w.transpose();
  }
  if (has_offset_) {
    JacobianBlock& J_r_velocity = (*H)[velocitySlot()];
    J_r_velocity.resize(1, 3);
    J_r_velocity = (dt_s_ * inv_sigma_) * (to_a.u_w - to_b.u_w).transpose();  // d p_w_tag / d v_w = dt I
  }
}

}  // namespace rilo
