#include "estimation/ekf/ekf_measurement_models.h"

#include "estimation/factors/range_factor.h"

namespace rilo {
namespace {

/// Row g_w^T dp_w_tag / d[dtheta, dp] for a world gradient g_w: with
/// dp_w_tag = -R [l]x dtheta + dp and a = R^T g, -a^T [l]x = (l x a)^T, so
/// the row is [ (p_b_tag x R^T g)^T , g^T ].
Eigen::Matrix<double, 1, 6> tagGradientRow(const Mat3& R_w_b, const Vec3& p_b_tag, const Vec3& g_w) {
  Eigen::Matrix<double, 1, 6> row;
  row.head<3>() = p_b_tag.cross(R_w_b.transpose() * g_w).transpose();
  row.tail<3>() = g_w.transpose();
  return row;
}

}  // namespace

EkfPrediction<1> predictRange(const EkfState& x, const Vec3& p_w_anchor, const Vec3& p_b_tag) {
  const RangeAndDirection rd = rangeAndDirection(x.R_w_b * p_b_tag + x.p_w_b - p_w_anchor);
  EkfPrediction<1> out;
  out.h(0) = rd.range_m;
  out.H = tagGradientRow(x.R_w_b, p_b_tag, rd.u_w);
  return out;
}

EkfPrediction<1> predictTdoa(const EkfState& x, const Vec3& p_w_anchor_a, const Vec3& p_w_anchor_b,
                             const Vec3& p_b_tag) {
  const Vec3 p_w_tag = x.R_w_b * p_b_tag + x.p_w_b;
  const RangeAndDirection to_a = rangeAndDirection(p_w_tag - p_w_anchor_a);
  const RangeAndDirection to_b = rangeAndDirection(p_w_tag - p_w_anchor_b);
  EkfPrediction<1> out;
  out.h(0) = to_b.range_m - to_a.range_m;
  out.H = tagGradientRow(x.R_w_b, p_b_tag, to_b.u_w - to_a.u_w);
  return out;
}

EkfPrediction<2> predictUltrasonic(const EkfState& x, const Vec3& p_w_anchor, const Vec3& p_b_us) {
  const Vec3 d_w = x.R_w_b * p_b_us + x.p_w_b - p_w_anchor;
  const RangeAndDirection rd = rangeAndDirection(d_w);
  const Vec3 n_w = Vec3::UnitZ();
  EkfPrediction<2> out;
  out.h << rd.range_m, n_w.dot(d_w);
  out.H.row(0) = tagGradientRow(x.R_w_b, p_b_us, rd.u_w);
  out.H.row(1) = tagGradientRow(x.R_w_b, p_b_us, n_w);
  return out;
}

}  // namespace rilo
