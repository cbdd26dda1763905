#pragma once
// UWB time-difference-of-arrival between anchors a and b, as a range
// difference (recording format, tdoa.csv):
//   p_w_tag = R_w_b * p_b_tag + p_w_b
//   h       = |p_w_tag - p_w_anchor_b| - |p_w_tag - p_w_anchor_a|     (m)
//   r       = (z - h) / sigma                                        (whitened, 1-dim)
//
// Sign: r > 0 <=> the signal from b arrived LATER than predicted relative to
// the signal from a. NLOS delay on anchor b therefore shows up as r > 0 and
// NLOS delay on anchor a as r < 0. Because either anchor can be blocked,
// symmetric losses (Huber, Cauchy) are the natural choice; an asymmetric
// (NLOS-tail) loss is allowed but only down-weights NLOS on b, and treats NLOS
// on a as if it were on the Gaussian side. The caller decides.
//
// A row measured dt after its state's time sees the tag where the state's
// velocity takes it, p_w_tag + v_w dt (RangeTimeOffset, as a two-way range).
//
// Anchors are both variables (keys {X_i, L_a, L_b}) or both constants (key
// {X_i}), then the offset's velocity key V_i if given. Jacobians are in rilo's retraction charts (pose [phi; rho], Vec3
// additive). Near a singular configuration (tag on an anchor) the direction
// convention of rangeAndDirection() in range_factor.h applies.
#include <optional>

#include "estimation/factors/range_factor.h"

namespace rilo {

class TdoaFactor final : public Factor {
 public:
  /// Anchors as variables: keys {pose_key, anchor_a_key, anchor_b_key}, then
  /// the offset's velocity key if given. Throws std::invalid_argument on
  /// non-finite diff/lever arm/offset, sigma_m <= 0 or repeated keys.
  TdoaFactor(Key pose_key, Key anchor_a_key, Key anchor_b_key, double diff_m, double sigma_m, const Vec3& p_b_tag,
             RobustLossPtr loss = nullptr, std::optional<RangeTimeOffset> offset = std::nullopt);
  /// Anchors as constants (world, m): key {pose_key}, then the offset's
  /// velocity key if given. Throws std::invalid_argument also when the two
  /// anchors coincide (the measurement carries no information).
  TdoaFactor(Key pose_key, const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b, double diff_m, double sigma_m,
             const Vec3& p_b_tag, RobustLossPtr loss = nullptr, std::optional<RangeTimeOffset> offset = std::nullopt);

  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  Key poseKey() const { return keys()[0]; }
  bool anchorsAreVariables() const { return anchors_are_variables_; }
  /// Anchor variable keys; throw std::logic_error for constant anchors.
  Key anchorAKey() const;
  Key anchorBKey() const;
  /// Anchor positions: stored constants, or the variables' values in x.
  Vec3 anchorAPosition(const Values& x) const;
  Vec3 anchorBPosition(const Values& x) const;
  double measuredDifference() const { return diff_m_; }  ///< z (m)
  double sigma() const { return sigma_m_; }               ///< std-dev of the difference (m)
  const Vec3& leverArm() const { return p_b_tag_; }       ///< tag antenna in body frame (m)
  /// h(x) = |p_tag - A_b| - |p_tag - A_a| (m), p_tag at the row's time.
  double predictedDifference(const Values& x) const;
  /// Row time minus state time (s); 0 without an offset.
  double timeOffset() const { return dt_s_; }
  bool hasTimeOffset() const { return has_offset_; }

 private:
  double diff_m_;      ///< measured range difference z (m)
  double sigma_m_;     ///< standard deviation of z (m)
  double inv_sigma_;   ///< 1 / sigma_m_ (1/m)
  Vec3 p_b_tag_;       ///< tag antenna lever arm, body frame (m)
  Vec3 p_w_anchor_a_;  ///< constant anchor a, world (m); unused if variables
  Vec3 p_w_anchor_b_;  ///< constant anchor b, world (m); unused if variables
  bool anchors_are_variables_;
  bool has_offset_ = false;  ///< keys end with the state's velocity
  double dt_s_ = 0.0;        ///< row time minus state time (s)

  int velocitySlot() const { return anchors_are_variables_ ? 3 : 1; }
  Vec3 tagPosition(const Values& x) const;  ///< p_w_tag at the row's time
};

}  // namespace rilo
