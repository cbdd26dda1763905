#pragma once
// Ultrasonic range with an optional elevation constraint (IMU-Ultrasonic-UWB paper,
// Sec. III-C4 eq. 18-20 and Sec. III-D3 eq. 26).
//
// The IMU-Ultrasonic-UWB paper's formulas did not survive text extraction; its prose defines a
// range residual to an ultrasonic anchor, plus "an elevation constraint based
// on the vertical component of the tag position", n^T (p_tag - p_anchor) -
// delta_h with n the vertical normal and delta_h the height difference between
// tag and anchor, stacked into one residual. Our interpretation:
//
//   p_w_tag = R_w_b * p_b_us + p_w_b         (ultrasonic receiver lever arm)
//   d_w     = p_w_tag - p_w_anchor
//   r       = [ (z - |d_w|) / sigma_range          ]   always
//             [ (n^T d_w - delta_h) / sigma_height ]   only with UltrasonicElevation
//
// with n = (0, 0, 1), the world vertical (z up, recording format). delta_h is
// the expected height of the receiver relative to the anchor (m; negative
// when the anchor is mounted above), e.g. from a known mounting height of the
// tag on a vehicle; sigma_height says how well that height is known.
//
// Signs: row 0 follows the range convention (r > 0 <=> measured longer than
// predicted, the NLOS side). Row 1 is as in the IMU-Ultrasonic-UWB paper, predicted minus expected
// height difference (r > 0 <=> the tag is higher than delta_h says).
//
// Robust losses: the 1-dim form passes the signed residual to any loss. The
// 2-dim form applies rho(|r|) (Factor base), which is only meaningful for a
// symmetric loss, so an asymmetric loss with an elevation row is rejected in
// the constructor.
//
// A range measured dt after its state's time sees the receiver where the
// state's velocity takes it, p_w_tag + v_w dt (RangeTimeOffset): both rows.
//
// Anchor variable (keys {X_i, L_j}) or constant (key {X_i}), then the
// offset's velocity key V_i if given; Jacobians in
// rilo's retraction charts; the singular-direction convention of
// rangeAndDirection() (range_factor.h) applies when the receiver is on the anchor.
#include <optional>

#include "estimation/factors/range_factor.h"

namespace rilo {

/// Optional elevation row of an UltrasonicFactor.
struct UltrasonicElevation {
  double delta_h_m;     ///< expected n^T (p_w_tag - p_w_anchor): tag height above the anchor (m)
  double sigma_h_m;     ///< standard deviation of that height difference (m), > 0
};

class UltrasonicFactor final : public Factor {
 public:
  /// Anchor as a variable: keys {pose_key, anchor_key}, then the offset's
  /// velocity key if given. Throws std::invalid_argument on non-finite inputs,
  /// non-positive sigmas, repeated keys, or an asymmetric loss together with
  /// an elevation row.
  UltrasonicFactor(Key pose_key, Key anchor_key, double range_m, double sigma_range_m, const Vec3& p_b_us,
                   std::optional<UltrasonicElevation> elevation = std::nullopt, RobustLossPtr loss = nullptr,
                   std::optional<RangeTimeOffset> offset = std::nullopt);
  /// Anchor as a constant p_w_anchor (world, m): key {pose_key}, then the offset's velocity key if given.
  UltrasonicFactor(Key pose_key, const Vec3& p_w_anchor, double range_m, double sigma_range_m, const Vec3& p_b_us,
                   std::optional<UltrasonicElevation> elevation = std::nullopt, RobustLossPtr loss = nullptr,
                   std::optional<RangeTimeOffset> offset = std::nullopt);

  /// 1 (range only) or 2 (range and elevation).
  int dim() const override { return elevation_ ? 2 : 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  Key poseKey() const { return keys()[0]; }
  bool anchorIsVariable() const { return anchor_is_variable_; }
  /// Anchor variable key; throws std::logic_error for a constant anchor.
  Key anchorKey() const;
  /// Anchor position: the stored constant, or the anchor variable's value in x.
  Vec3 anchorPosition(const Values& x) const;
  double measuredRange() const { return range_m_; }          ///< z (m)
  double sigmaRange() const { return sigma_range_m_; }        ///< range std-dev (m)
  const std::optional<UltrasonicElevation>& elevation() const { return elevation_; }
  const Vec3& leverArm() const { return p_b_us_; }            ///< receiver in body frame (m)
  /// Range time minus state time (s); 0 without an offset.
  double timeOffset() const { return dt_s_; }
  bool hasTimeOffset() const { return has_offset_; }
  /// Vertical normal n (world), (0, 0, 1).
  static Vec3 verticalNormal() { return Vec3::UnitZ(); }
  /// |p_tag - p_anchor| (m).
  double predictedRange(const Values& x) const;
  /// n^T (p_tag - p_anchor) (m).
  double predictedHeightDifference(const Values& x) const;

 private:
  void validate() const;  // checks shared by both constructors

  double range_m_;                                 ///< measured range z (m)
  double sigma_range_m_;                           ///< range std-dev (m)
  double inv_sigma_range_;                         ///< 1 / sigma_range_m_ (1/m)
  Vec3 p_b_us_;                                    ///< ultrasonic receiver lever arm, body frame (m)
  Vec3 p_w_anchor_;                                ///< constant anchor, world (m); unused if variable
  std::optional<UltrasonicElevation> elevation_;   ///< elevation row, if any
  bool anchor_is_variable_;
  bool has_offset_ = false;  ///< keys end with the state's velocity
  double dt_s_ = 0.0;        ///< range time minus state time (s)

  int velocitySlot() const { return anchor_is_variable_ ? 2 : 1; }
  Vec3 receiverPosition(const Values& x) const;  ///< p_w_tag at the range's time
};

}  // namespace rilo
