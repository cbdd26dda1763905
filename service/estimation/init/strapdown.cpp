#include "estimation/init/strapdown.h"

#include <algorithm>

namespace rilo {

StrapdownDelta::Corrected StrapdownDelta::corrected(const ImuBias& b) const {
  Corrected c;
  c.dR = dR * so3::exp(dR_dbg * b.gyro);
  c.dv = dv + dv_dba * b.accel + dv_dbg * b.gyro;
  c.dp = dp + dp_dba * b.accel + dp_dbg * b.gyro;
  return c;
}

StrapdownState propagate(const StrapdownDelta& d, const Pose3& T_w_r, const Vec3& v_w_r, const ImuBias& b,
                         double gravity_m_s2) {
  const StrapdownDelta::Corrected c = d.corrected(b);
  const Vec3 g_w(0.0, 0.0, -gravity_m_s2);
  StrapdownState s;
  s.T_w_b = Pose3(so3::normalize(T_w_r.R * c.dR), T_w_r.p + v_w_r * d.dt_s + 0.5 * g_w * d.dt_s * d.dt_s + T_w_r.R * c.dp);
  s.v_w = v_w_r + g_w * d.dt_s + T_w_r.R * c.dv;
  return s;
}

namespace {

/// One zero-order-hold step of h seconds with the raw sample (a, w).
void step(StrapdownDelta& d, const Vec3& a, const Vec3& w, double h) {
  if (h <= 0.0) return;
  const Mat3 hat_a = so3::hat(a);
  // Jacobians first: they use the rotation at the start of the step.
  d.dp_dba += d.dv_dba * h - 0.5 * h * h * d.dR;
  d.dp_dbg += d.dv_dbg * h - 0.5 * h * h * d.dR * hat_a * d.dR_dbg;
  d.dv_dba -= h * d.dR;
  d.dv_dbg -= h * d.dR * hat_a * d.dR_dbg;
  d.dp += d.dv * h + 0.5 * h * h * d.dR * a;
  d.dv += h * d.dR * a;
  const Vec3 phi = w * h;
  const Mat3 inc = so3::exp(phi);
  d.dR_dbg = inc.transpose() * d.dR_dbg - h * so3::rightJacobian(phi);
  d.dR = d.dR * inc;
}

}  // namespace

std::vector<StrapdownDelta> integrateStrapdown(std::span<const ImuSample> imu, std::int64_t t_ref_ns,
                                               const std::vector<std::int64_t>& query_t_ns) {
  std::vector<StrapdownDelta> out;
  if (imu.empty()) return out;
  out.reserve(query_t_ns.size());

  // The sample in effect at t_ref: the last one at or before it (else the first).
  std::size_t k = 0;
  while (k + 1 < imu.size() && imu[k + 1].t_ns <= t_ref_ns) ++k;

  StrapdownDelta d;
  std::int64_t t_cur = t_ref_ns;
  int steps_since_normalize = 0;
  for (std::int64_t t_q : query_t_ns) {
    t_q = std::max(t_q, t_cur);  // queries are ascending; a stray earlier one gets the current delta
    while (t_cur < t_q) {
      // Sample k holds until the next sample (or forever after the last one).
      const std::int64_t t_hold_end = k + 1 < imu.size() ? imu[k + 1].t_ns : t_q;
      const std::int64_t t_next = std::min(t_q, std::max(t_hold_end, t_cur));
      step(d, imu[k].accel_m_s2, imu[k].gyro_rad_s, 1e-9 * static_cast<double>(t_next - t_cur));
      t_cur = t_next;
      if (++steps_since_normalize >= 200) {
        d.dR = so3::normalize(d.dR);
        steps_since_normalize = 0;
      }
      if (k + 1 < imu.size() && t_cur >= imu[k + 1].t_ns) ++k;
    }
    d.t_ns = t_q;
    d.dt_s = 1e-9 * static_cast<double>(t_q - t_ref_ns);
    out.push_back(d);
  }
  return out;
}

}  // namespace rilo
