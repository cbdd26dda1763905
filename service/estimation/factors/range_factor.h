#pragma once
// UWB two-way range from a tag antenna on the body to an anchor.
//
// Measurement model (world frame, m):
//   p_w_tag = R_w_b * p_b_tag + p_w_b
//   h       = |p_w_tag - p_w_anchor|
//   r       = (z - h) / sigma                       (whitened, 1-dim)
// With a vertical weight w < 1 (setVerticalWeight) the vertical separation in
// h is dz_ref + w (dz - dz_ref): the range informs the heights w^2 as much.
//
// A range measured dt after its state's time (ranges a few tens of ms apart
// share one state, RangeImuGraphParams::same_state_window_ns) sees the tag
// where the state's velocity takes it: p_w_tag + v_w dt (RangeTimeOffset).
// Left out, and small against the range sigma at dt <= 50 ms: half the
// acceleration times dt^2 (walking, < 4 mm) and the lever arm's turn over dt
// (< 1 cm at 2 rad/s).
//
// Sign convention: r > 0 <=> the measured range is LONGER than predicted, the
// side NLOS propagation produces (a blocked direct path only adds delay). The
// robust losses in estimation/noise rely on this sign (asymmetric losses put
// their heavy tail on r > 0), so it must not be flipped.
//
// The anchor is either a variable (key L_j, a Vec3 with its own prior, e.g.
// from the survey) or a constant position stored in the factor.
//
// Jacobians are in rilo's retraction charts: pose tangent [phi; rho] with
// R' = R Exp(phi), p' = p + R rho; the anchor Vec3 is additive.
//
// Singular configuration: when the tag sits on the anchor (h below
// kMinRangeForDirection_m) |.| has no derivative. The factor then uses the
// fixed world unit direction (0, 0, -1), i.e. treats the tag as just below the
// anchor (anchors are normally mounted above the tag); this is a valid
// subgradient of |.| at 0, keeps r and H finite, and lets a solver move the
// tag off the anchor along a deterministic direction.
#include <optional>
#include <vector>

#include "estimation/graph/factor.h"

namespace rilo {

/// Below this distance (m) the tag-to-anchor direction is taken as (0, 0, -1).
inline constexpr double kMinRangeForDirection_m = 1e-9;

/// Distance and unit direction of a tag-minus-anchor vector d_w = p_w_tag - p_w_anchor.
struct RangeAndDirection {
  double range_m;  ///< |d_w| (m); exact, also in the singular case
  Vec3 u_w;        ///< d_w / |d_w|; (0, 0, -1) when |d_w| < kMinRangeForDirection_m
};
RangeAndDirection rangeAndDirection(const Vec3& d_w);

/// Jacobian of g_w^T p_w_tag w.r.t. the pose tangent [phi; rho], where
/// p_w_tag = R_w_b p_b_tag + p_w_b and g_w is a world-frame gradient row:
///   [ (p_b_tag x R^T g)^T , (R^T g)^T ].
Eigen::Matrix<double, 1, 6> tagPointGradientToPoseTangent(const Mat3& R_w_b, const Vec3& p_b_tag, const Vec3& g_w);

/// A range measured dt_s after the time of the state it is attached to.
struct RangeTimeOffset {
  Key velocity_key;  ///< the state's world-frame velocity (Vec3, m/s)
  double dt_s;       ///< range time minus state time (s), finite
};

/// A range-like factor's keys: `keys`, then the offset's velocity key if
/// given. Throws std::invalid_argument naming `factor` when the velocity key
/// repeats one of the others. Shared by RangeFactor, TdoaFactor and
/// UltrasonicFactor.
std::vector<Key> withVelocityKey(std::vector<Key> keys, const std::optional<RangeTimeOffset>& offset,
                                 const char* factor);

class RangeFactor final : public Factor {
 public:
  /// Anchor as a variable: keys {pose_key (Pose3 T_w_b), anchor_key (Vec3 p_w_anchor)},
  /// then the offset's velocity key if given.
  /// Throws std::invalid_argument on non-finite range/lever arm/offset, sigma_m <= 0 or
  /// repeated keys.
  RangeFactor(Key pose_key, Key anchor_key, double range_m, double sigma_m, const Vec3& p_b_tag,
              RobustLossPtr loss = nullptr, std::optional<RangeTimeOffset> offset = std::nullopt);
  /// Anchor as a constant p_w_anchor (m, world): key {pose_key}, then the offset's velocity key if given.
  RangeFactor(Key pose_key, const Vec3& p_w_anchor, double range_m, double sigma_m, const Vec3& p_b_tag,
              RobustLossPtr loss = nullptr, std::optional<RangeTimeOffset> offset = std::nullopt);

  int dim() const override { return 1; }
  void evaluate(const Values& x, Residual& r, Jacobians* H) const override;

  Key poseKey() const { return keys()[0]; }
  bool anchorIsVariable() const { return anchor_is_variable_; }
  /// Anchor variable key; throws std::logic_error for a constant anchor.
  Key anchorKey() const;
  /// Anchor position: the stored constant, or the anchor variable's value in x.
  Vec3 anchorPosition(const Values& x) const;
  /// Lets the range speak to the tag's height only with weight w in [0, 1]:
  /// the prediction takes the tag's height above the anchor as
  /// dz_ref + w (dz - dz_ref), dz = p_w_tag.z - p_w_anchor.z, dz_ref a
  /// constant (m; the reference height less the surveyed anchor's). The
  /// separation, not the tag's height alone, so that an anchor variable's
  /// height cannot take over what the tag's no longer may. 1 (the default):
  /// the plain model. Far anchors tell almost nothing about the height and
  /// their unremoved NLOS excess a lot (RangeImuGraphStream::verticalWeightOf
  /// chooses w). Throws std::invalid_argument unless w is in [0, 1] and
  /// dz_ref_m finite.
  void setVerticalWeight(double w, double dz_ref_m);
  double verticalWeight() const { return vertical_weight_; }
  /// Range time minus state time (s); 0 without an offset.
  double timeOffset() const { return dt_s_; }
  bool hasTimeOffset() const { return has_offset_; }
  double measuredRange() const { return range_m_; }  ///< z (m)
  double sigma() const { return sigma_m_; }           ///< range std-dev (m)
  const Vec3& leverArm() const { return p_b_tag_; }   ///< tag antenna in body frame (m)
  /// h(x) = |R p_b_tag + p + v dt - p_w_anchor| (m).
  double predictedRange(const Values& x) const;

 private:
  /// Tag antenna at the range's time minus anchor as the prediction sees it
  /// (the vertical separation weighted, see setVerticalWeight).
  Vec3 separation(const Values& x, const Pose3& T_w_b, const Vec3& p_w_anchor) const;
  int velocitySlot() const { return anchor_is_variable_ ? 2 : 1; }

  double range_m_;        ///< measured range z (m)
  double sigma_m_;        ///< range standard deviation (m)
  double inv_sigma_;      ///< 1 / sigma_m_ (1/m)
  Vec3 p_b_tag_;          ///< tag antenna lever arm, body frame (m)
  Vec3 p_w_anchor_;       ///< constant anchor position, world (m); unused if variable
  bool anchor_is_variable_;
  double vertical_weight_ = 1.0;  ///< w: share of the tag's height the prediction follows
  double dz_ref_m_ = 0.0;         ///< vertical separation (m) the prediction is pinned to for w < 1
  bool has_offset_ = false;       ///< keys end with the state's velocity
  double dt_s_ = 0.0;             ///< range time minus state time (s)
};

}  // namespace rilo
