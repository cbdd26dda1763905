#include "estimation/factors/range_factor.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {
namespace {

void requireFinite(double v, const char* name) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("RangeFactor: ") + name + " must be finite");
}
void requireFinite(const Vec3& v, const char* name) {
  if (!v.allFinite()) throw std::invalid_argument(std::string("RangeFactor: ") + name + " must be finite");
}
void requirePositive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0)) {
    throw std::invalid_argument(std::string("RangeFactor: ") + name + " must be positive and finite, got " +
                                std::to_string(v));
  }
}

}  // namespace

std::vector<Key> withVelocityKey(std::vector<Key> keys, const std::optional<RangeTimeOffset>& offset,
                                 const char* factor) {
  if (!offset) return keys;
  for (Key k : keys) {
    if (k == offset->velocity_key) {
      throw std::invalid_argument(std::string(factor) + ": the velocity key must differ from the other keys");
    }
  }
  keys.push_back(offset->velocity_key);
  return keys;
}

RangeAndDirection rangeAndDirection(const Vec3& d_w) {
  const double range_m = d_w.norm();
  if (range_m < kMinRangeForDirection_m) return {range_m, Vec3(0.0, 0.0, -1.0)};
  return {range_m, d_w / range_m};
}

Eigen::Matrix<double, 1, 6> tagPointGradientToPoseTangent(const Mat3& R_w_b, const Vec3& p_b_tag, const Vec3& g_w) {
  // d p_w_tag = -R hat(p_b_tag) d_phi + R d_rho, and a^T hat(l) = (a x l)^T.
  const Vec3 g_b = R_w_b.transpose() * g_w;
  Eigen::Matrix<double, 1, 6> J;
  J.head<3>() = p_b_tag.cross(g_b).transpose();
  J.tail<3>() = g_b.transpose();
  return J;
}

RangeFactor::RangeFactor(Key pose_key, Key anchor_key, double range_m, double sigma_m, const Vec3& p_b_tag,
                         RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key, anchor_key}, offset, "RangeFactor"), std::move(loss)),
      range_m_(range_m),
      sigma_m_(sigma_m),
      inv_sigma_(1.0 / sigma_m),
      p_b_tag_(p_b_tag),
      p_w_anchor_(Vec3::Zero()),
      anchor_is_variable_(true),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  requireFinite(range_m, "range_m");
  requirePositive(sigma_m, "sigma_m");
  requireFinite(p_b_tag, "p_b_tag");
  requireFinite(dt_s_, "time offset");
  if (pose_key == anchor_key) throw std::invalid_argument("RangeFactor: pose_key and anchor_key must differ");
}

RangeFactor::RangeFactor(Key pose_key, const Vec3& p_w_anchor, double range_m, double sigma_m,
                         const Vec3& p_b_tag, RobustLossPtr loss, std::optional<RangeTimeOffset> offset)
    : Factor(withVelocityKey({pose_key}, offset, "RangeFactor"), std::move(loss)),
      range_m_(range_m),
      sigma_m_(sigma_m),
      inv_sigma_(1.0 / sigma_m),
      p_b_tag_(p_b_tag),
      p_w_anchor_(p_w_anchor),
      anchor_is_variable_(false),
      has_offset_(offset.has_value()),
      dt_s_(offset ? offset->dt_s : 0.0) {
  requireFinite(range_m, "range_m");
  requirePositive(sigma_m, "sigma_m");
  requireFinite(p_b_tag, "p_b_tag");
  requireFinite(p_w_anchor, "p_w_anchor");
  requireFinite(dt_s_, "time offset");
}

Key RangeFactor::anchorKey() const {
  if (!anchor_is_variable_) throw std::logic_error("RangeFactor::anchorKey: the anchor is a constant");
  return keys()[1];
}

Vec3 RangeFactor::anchorPosition(const Values& x) const {
  return anchor_is_variable_ ? x.vec3(keys()[1]) : p_w_anchor_;
}

void RangeFactor::setVerticalWeight(double w, double dz_ref_m) {
  if (!(w >= 0.0 && w <= 1.0)) {
    throw std::invalid_argument("RangeFactor: vertical weight must lie in [0, 1], got " + std::to_string(w));
  }
  requireFinite(dz_ref_m, "dz_ref_m");
  vertical_weight_ = w;
  dz_ref_m_ = dz_ref_m;
}

Vec3 RangeFactor::separation(const Values& x, const Pose3& T_w_b, const Vec3& p_w_anchor) const {
  Vec3 d_w = T_w_b.transformFrom(p_b_tag_) - p_w_anchor;
  if (has_offset_) d_w += dt_s_ * x.vec3(keys()[velocitySlot()]);
  if (vertical_weight_ != 1.0) d_w.z() = dz_ref_m_ + vertical_weight_ * (d_w.z() - dz_ref_m_);
  return d_w;
}

double RangeFactor::predictedRange(const Values& x) const {
  return separation(x, x.pose(keys()[0]), anchorPosition(x)).norm();
}

void RangeFactor::evaluate(const Values& x, Residual& r, Jacobians* H) const {
  const Pose3& T_w_b = x.pose(keys()[0]);
  const Vec3& p_w_anchor = anchor_is_variable_ ? x.vec3(keys()[1]) : p_w_anchor_;
  const RangeAndDirection rd = rangeAndDirection(separation(x, T_w_b, p_w_anchor));

  r.resize(1);
  r(0) = (range_m_ - rd.range_m) * inv_sigma_;
  if (H == nullptr) return;

  // dr/dp_w_tag = -u^T / sigma; dr/dp_w_anchor = +u^T / sigma.
  JacobianBlock& J_r_pose = (*H)[0];
  J_r_pose.resize(1, 6);
  Vec3 g_w = -inv_sigma_ * rd.u_w;
  g_w.z() *= vertical_weight_;  // d(dz_ref + w (dz - dz_ref)) / d dz = w
  J_r_pose = tagPointGradientToPoseTangent(T_w_b.R, p_b_tag_, g_w);
  if (anchor_is_variable_) {
    JacobianBlock& J_r_anchor = (*H)[1];
    J_r_anchor.resize(1, 3);
    J_r_anchor = inv_sigma_ * rd.u_w.transpose();
    J_r_anchor(0, 2) *= vertical_weight_;
  }
  if (has_offset_) {
    JacobianBlock& J_r_velocity = (*H)[velocitySlot()];
    J_r_velocity.resize(1, 3);
    J_r_velocity = dt_s_ * g_w.transpose();  // d p_w_tag / d v_w = dt I
  }
}

}  // namespace rilo
