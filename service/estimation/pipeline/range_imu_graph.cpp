#include "estimation/pipeline/range_imu_graph.h"

#include <stdexcept>

#include "estimation/factors/imu_factor.h"
#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/imu/preintegration.h"

namespace rilo {
namespace {

constexpr double kNsToS = 1e-9;

/// Integrates the zero-order-held IMU samples over [t_a, t_b] into pim,
/// advancing `cursor` (index of the sample in effect at t_a).
void integrateInterval(const std::vector<ImuSample>& imu, std::size_t& cursor, std::int64_t t_a_ns,
                       std::int64_t t_b_ns, PreintegratedImu& pim) {
  std::int64_t t = t_a_ns;
  while (t < t_b_ns) {
    const std::int64_t t_next =
        cursor + 1 < imu.size() ? std::min(imu[cursor + 1].t_ns, t_b_ns) : t_b_ns;
    if (t_next > t) {
      pim.integrate(imu[cursor].accel_m_s2, imu[cursor].gyro_rad_s, static_cast<double>(t_next - t) * kNsToS);
      t = t_next;
    }
    if (cursor + 1 < imu.size() && imu[cursor + 1].t_ns <= t) ++cursor;
  }
}

}  // namespace

RangeImuGraph buildRangeImuGraph(const std::vector<ImuSample>& imu, const std::vector<RangeSample>& ranges,
                                 const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess,
                                 const Vec3& v_w0_guess, const RangeImuGraphParams& params) {
  params.imu.validate();
  if (imu.empty() || ranges.empty()) throw std::invalid_argument("buildRangeImuGraph: no IMU samples or no ranges");
  for (std::size_t k = 1; k < imu.size(); ++k) {
    if (imu[k].t_ns <= imu[k - 1].t_ns) throw std::invalid_argument("buildRangeImuGraph: IMU samples not increasing at index " + std::to_string(k));
  }
  for (std::size_t k = 1; k < ranges.size(); ++k) {
    if (ranges[k].t_ns < ranges[k - 1].t_ns) throw std::invalid_argument("buildRangeImuGraph: ranges not sorted at index " + std::to_string(k));
  }
  if (ranges.front().t_ns < imu.front().t_ns || ranges.back().t_ns > imu.back().t_ns) {
    throw std::invalid_argument("buildRangeImuGraph: ranges outside the IMU's time span");
  }

  RangeImuGraph out;
  const RobustLossPtr loss = makeRangeLoss(params.range_loss, params.range_noise);
  std::vector<bool> anchor_used(p_w_anchors.size(), false);

  if (params.same_state_window_ns < 0) throw std::invalid_argument("buildRangeImuGraph: same_state_window_ns must be >= 0");
  if (params.max_state_interval_ns <= params.same_state_window_ns) {
    throw std::invalid_argument("buildRangeImuGraph: max_state_interval_ns must exceed same_state_window_ns");
  }
  // States: a new one whenever a range is farther than the window from the
  // last state; evenly spaced IMU-only states fill longer ranging gaps.
  std::vector<std::size_t> state_of_range(ranges.size());
  for (std::size_t k = 0; k < ranges.size(); ++k) {
    if (out.state_t_ns.empty() || ranges[k].t_ns - out.state_t_ns.back() > params.same_state_window_ns) {
      if (!out.state_t_ns.empty()) {
        const std::int64_t t_last = out.state_t_ns.back();
        const std::int64_t gap = ranges[k].t_ns - t_last;
        const std::int64_t pieces = (gap + params.max_state_interval_ns - 1) / params.max_state_interval_ns;
        for (std::int64_t j = 1; j < pieces; ++j) out.state_t_ns.push_back(t_last + gap * j / pieces);
      }
      out.state_t_ns.push_back(ranges[k].t_ns);
    }
    state_of_range[k] = out.state_t_ns.size() - 1;
  }

  // First-state priors.
  out.graph.emplace<PriorPose3Factor>(sym::X(0), T_w_b0_guess, params.first_pose_sigmas);
  out.graph.emplace<PriorVec3Factor>(sym::V(0), v_w0_guess, Vec3(Vec3::Constant(params.first_velocity_sigma_m_s)));
  Vec6 bias_sigmas;
  bias_sigmas << Vec3::Constant(params.first_accel_bias_sigma), Vec3::Constant(params.first_gyro_bias_sigma);
  out.graph.emplace<PriorBiasFactor>(sym::B(0), ImuBias(), bias_sigmas);

  // IMU factors between consecutive states.
  std::size_t cursor = 0;
  while (cursor + 1 < imu.size() && imu[cursor + 1].t_ns <= out.state_t_ns.front()) ++cursor;
  PreintegratedImu pim(params.imu, ImuBias(), PreintegratedImu::CovarianceMode::kCombined);
  for (std::size_t i = 0; i + 1 < out.state_t_ns.size(); ++i) {
    pim.reset(ImuBias());
    integrateInterval(imu, cursor, out.state_t_ns[i], out.state_t_ns[i + 1], pim);
    out.graph.emplace<CombinedImuFactor>(sym::X(i), sym::V(i), sym::B(i), sym::X(i + 1), sym::V(i + 1),
                                         sym::B(i + 1), pim);
    ++out.imu_factors;
  }

  // Range factors.
  for (std::size_t k = 0; k < ranges.size(); ++k) {
    const RangeSample& r = ranges[k];
    if (r.anchor_id >= p_w_anchors.size()) {
      throw std::invalid_argument("buildRangeImuGraph: range " + std::to_string(k) + " names unknown anchor " +
                                  std::to_string(r.anchor_id));
    }
    const Key x = sym::X(state_of_range[k]);
    if (params.anchors_as_variables) {
      out.graph.emplace<RangeFactor>(x, sym::L(r.anchor_id), r.range_m, params.range_noise.sigma_m,
                                     params.p_b_tag, loss);
      anchor_used[r.anchor_id] = true;
    } else {
      out.graph.emplace<RangeFactor>(x, p_w_anchors[r.anchor_id], r.range_m, params.range_noise.sigma_m,
                                     params.p_b_tag, loss);
    }
    ++out.range_factors;
  }
  for (std::size_t a = 0; a < p_w_anchors.size(); ++a) {
    if (!anchor_used[a]) continue;
    out.graph.emplace<PriorVec3Factor>(sym::L(a), p_w_anchors[a], Vec3(Vec3::Constant(params.anchor_sigma_m)));
    out.anchor_keys.push_back(sym::L(a));
  }
  return out;
}

}  // namespace rilo
