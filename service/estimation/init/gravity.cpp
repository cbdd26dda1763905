#include "estimation/init/gravity.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "estimation/init/format.h"
#include "estimation/init/strapdown.h"

namespace rilo {

using init_detail::strprintf;

void GravityParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("GravityParams.") + field + " " + rule);
  };
  if (!(still_min_s >= 0.0)) fail("still_min_s", "must be >= 0");
  if (!(still_block_s > 0.0)) fail("still_block_s", "must be > 0");
  if (!(still_accel_std_m_s2 >= 0.0)) fail("still_accel_std_m_s2", "must be >= 0");
  if (!(still_gyro_rad_s >= 0.0)) fail("still_gyro_rad_s", "must be >= 0");
  if (!(max_speed_change_m_s >= 0.0)) fail("max_speed_change_m_s", "must be >= 0");
  if (!(min_tilt_sigma_rad > 0.0)) fail("min_tilt_sigma_rad", "must be > 0");
  if (!(gravity_tolerance_m_s2 > 0.0)) fail("gravity_tolerance_m_s2", "must be > 0");
}

double yawOf(const Mat3& R_w_b) { return std::atan2(R_w_b(1, 0), R_w_b(0, 0)); }

Mat3 yawRotation(double yaw_rad) { return Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ()).toRotationMatrix(); }

namespace {

struct BlockStats {
  double accel_std = 0.0;  ///< largest per-axis std-dev
  double gyro_mean = 0.0;  ///< mean |gyro|
  int n = 0;
};

BlockStats blockStats(std::span<const ImuSample> imu, std::int64_t t0, std::int64_t t1) {
  BlockStats s;
  Vec3 sum = Vec3::Zero(), sum2 = Vec3::Zero();
  double gyro = 0.0;
  auto first = std::lower_bound(imu.begin(), imu.end(), t0,
                                [](const ImuSample& m, std::int64_t t) { return m.t_ns < t; });
  for (auto it = first; it != imu.end(); ++it) {
    const ImuSample& m = *it;
    if (m.t_ns >= t1) break;
    sum += m.accel_m_s2;
    sum2 += m.accel_m_s2.cwiseAbs2();
    gyro += m.gyro_rad_s.norm();
    ++s.n;
  }
  if (s.n < 2) return s;
  const double n = s.n;
  const Vec3 var = (sum2 - sum.cwiseAbs2() / n) / (n - 1.0);
  s.accel_std = std::sqrt(std::max(0.0, var.maxCoeff()));
  s.gyro_mean = gyro / n;
  return s;
}

bool stillBlock(const BlockStats& b, const GravityParams& p) {
  return b.n >= 2 && b.accel_std <= p.still_accel_std_m_s2 && b.gyro_mean <= p.still_gyro_rad_s;
}

}  // namespace

std::vector<StillInterval> findStillIntervals(std::span<const ImuSample> imu, std::int64_t t0_ns, std::int64_t t1_ns,
                                              const GravityParams& params) {
  std::vector<StillInterval> out;
  const auto block_ns = static_cast<std::int64_t>(std::llround(params.still_block_s * 1e9));
  const auto min_ns = static_cast<std::int64_t>(std::llround(params.still_min_s * 1e9));
  StillInterval cur{t0_ns, t0_ns};
  auto close = [&] {
    if (cur.t1_ns > cur.t0_ns && cur.t1_ns - cur.t0_ns >= min_ns) out.push_back(cur);
  };
  for (std::int64_t b0 = t0_ns; b0 + block_ns <= t1_ns; b0 += block_ns) {
    if (stillBlock(blockStats(imu, b0, b0 + block_ns), params)) {
      if (cur.t1_ns != b0) {
        close();
        cur.t0_ns = b0;
      }
      cur.t1_ns = b0 + block_ns;
    }
  }
  close();
  return out;
}

GravityAlignment alignGravity(std::span<const ImuSample> imu, std::int64_t t_ref_ns, std::int64_t t_end_ns,
                              double gravity_m_s2, const GravityParams& params) {
  GravityAlignment g;
  if (imu.empty() || t_end_ns <= t_ref_ns) {
    g.message = "no IMU samples over the interval";
    return g;
  }
  // Still interval from t_ref on: consecutive quiet blocks.
  const auto block_ns = static_cast<std::int64_t>(std::llround(params.still_block_s * 1e9));
  g.accel_std_m_s2 = blockStats(imu, t_ref_ns, t_ref_ns + block_ns).accel_std;
  std::int64_t still_end = t_ref_ns;
  for (std::int64_t t0 = t_ref_ns; t0 + block_ns <= t_end_ns; t0 += block_ns) {
    if (!stillBlock(blockStats(imu, t0, t0 + block_ns), params)) break;
    still_end = t0 + block_ns;
  }
  const double still_s = 1e-9 * static_cast<double>(still_end - t_ref_ns);
  g.still = still_s >= params.still_min_s && still_s > 0.0;
  const std::int64_t t1 = g.still ? still_end : t_end_ns;
  g.interval_s = 1e-9 * static_cast<double>(t1 - t_ref_ns);

  const std::vector<StrapdownDelta> d = integrateStrapdown(imu, t_ref_ns, {t1});
  if (d.empty()) {
    g.message = "no IMU samples over the interval";
    return g;
  }
  const Vec3 f_mean = d.front().dv / g.interval_s;
  g.mean_specific_force_m_s2 = f_mean.norm();
  if (!f_mean.allFinite() || std::abs(g.mean_specific_force_m_s2 - gravity_m_s2) > params.gravity_tolerance_m_s2) {
    g.message = strprintf("the accelerometer does not measure gravity: mean specific force %.2f m/s^2 over %.1f s",
                       g.mean_specific_force_m_s2, g.interval_s);
    return g;
  }
  g.up_b = f_mean / g.mean_specific_force_m_s2;
  // Smallest rotation taking up_b to world up, then its yaw removed.
  const Mat3 R = Quat::FromTwoVectors(g.up_b, Vec3::UnitZ()).toRotationMatrix();
  g.R_w_b = so3::normalize(yawRotation(-yawOf(R)) * R);
  if (g.still) {
    g.tilt_sigma_rad = params.min_tilt_sigma_rad;
    g.message = strprintf("still for %.1f s: gravity from the mean specific force (accel std %.3f m/s^2)",
                       g.interval_s, g.accel_std_m_s2);
  } else {
    g.tilt_sigma_rad =
        std::max(params.min_tilt_sigma_rad, params.max_speed_change_m_s / (gravity_m_s2 * g.interval_s));
    g.message = strprintf("moving: gravity from the gyro-compensated mean specific force over %.1f s "
                       "(motion averaged out; tilt sigma %.1f deg)",
                       g.interval_s, g.tilt_sigma_rad * 180.0 / M_PI);
  }
  g.valid = true;
  return g;
}

}  // namespace rilo
