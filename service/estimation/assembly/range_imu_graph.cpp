#include "estimation/assembly/range_imu_graph.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "estimation/assembly/range_imu_graph_stream.h"

namespace rilo {

// The batch graph is the stream's output for the complete sample vectors, fed
// in time order (a range before an IMU sample of the same time) and never
// committing IMU-only states early, so that gap states split each ranging gap
// evenly. The increments are reassembled in the batch's factor order: the
// first-state priors, the IMU factors, the measurement factors in time order,
// the anchor priors in anchor order, the motion priors (height band, vertical
// speed) in state order.
TdoaModelParams tdoaModelParams(const RangeImuGraphParams& params) {
  TdoaModelParams t;
  t.loss = params.tdoa_loss;
  t.flagged_loss = params.tdoa_flagged_loss;
  t.sigma_m = params.tdoa_sigma_m;
  t.both_flagged_sigma_factor = params.tdoa_both_flagged_sigma_factor;
  t.one_flagged_sigma_factor = params.tdoa_one_flagged_sigma_factor;
  t.use_indicator = params.tdoa_nlos_indicator;
  t.max_power_gap_db = params.tdoa_max_power_gap_db;
  return t;
}

double verticalSpeedPriorSigma(const RangeImuGraphParams& params, std::int64_t interval_ns) {
  const double tau_s = params.vertical_speed_correlation_s;
  const double interval_s = std::max(1e-3, 1e-9 * static_cast<double>(interval_ns));
  return params.vertical_speed_sigma_m_s * std::sqrt(tau_s / std::min(interval_s, tau_s));
}

RangeImuGraph buildRangeImuGraph(const std::vector<ImuSample>& imu, const std::vector<RangeSample>& ranges,
                                 const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess,
                                 const Vec3& v_w0_guess, const RangeImuGraphParams& params) {
  std::vector<Measurement> measurements;
  measurements.reserve(ranges.size());
  for (const RangeSample& r : ranges) measurements.push_back(Measurement::of(r));
  return buildRangeImuGraph(imu, measurements, p_w_anchors, T_w_b0_guess, v_w0_guess, params);
}

RangeImuGraph buildRangeImuGraph(const std::vector<ImuSample>& imu, const std::vector<Measurement>& ranges,
                                 const std::vector<Vec3>& p_w_anchors, const Pose3& T_w_b0_guess,
                                 const Vec3& v_w0_guess, const RangeImuGraphParams& params) {
  RangeImuStreamOptions options;
  options.max_range_wait_ns = RangeImuStreamOptions::kWaitForever;
  RangeImuGraphStream stream(p_w_anchors, params, options);  // validates params
  if (imu.empty() || ranges.empty()) throw std::invalid_argument("buildRangeImuGraph: no IMU samples or no ranges");
  // Every state must lie inside the IMU's span, or the stream would wait for more IMU.
  if (ranges.front().t_ns < imu.front().t_ns || ranges.back().t_ns > imu.back().t_ns) {
    throw std::invalid_argument("buildRangeImuGraph: ranges outside the IMU's time span");
  }

  RangeImuGraph out;
  FactorGraph imu_factors, range_factors, motion_priors;
  std::vector<FactorPtr> anchor_priors(p_w_anchors.size());
  StateEstimate previous;  // bias_hat stays zero: every IMU factor is preintegrated without bias
  auto collect = [&](const GraphIncrement& inc) {
    std::size_t f = 0;
    if (inc.new_state) {
      out.state_t_ns.push_back(inc.t_ns);
      if (inc.state_index == 0) {
        for (; f < 3; ++f) out.graph.add(inc.factors[f]);
      } else {
        imu_factors.add(inc.factors[f++]);
      }
      previous.index = inc.state_index;
      previous.t_ns = inc.t_ns;
      previous.T_w_b = inc.values.pose(sym::X(inc.state_index));
      previous.v_w = inc.values.vec3(sym::V(inc.state_index));
    }
    for (std::size_t k = 0; k < inc.range_factors; ++k) range_factors.add(inc.factors[f++]);
    for (Key l : inc.new_anchor_keys) anchor_priors[keyIndex(l)] = inc.factors[f++];
    if (inc.new_state) {
      while (f < inc.factors.size()) motion_priors.add(inc.factors[f++]);  // height band, vertical speed
    }
    if (f != inc.factors.size()) throw std::logic_error("buildRangeImuGraph: unexpected increment layout");
  };
  auto drain = [&] {
    while (std::optional<GraphIncrement> inc = stream.next(previous)) collect(*inc);
  };

  collect(stream.start(ranges.front().t_ns, T_w_b0_guess, v_w0_guess));
  std::size_t i = 0, k = 0;
  while (i < imu.size() || k < ranges.size()) {
    if (k < ranges.size() && (i == imu.size() || ranges[k].t_ns <= imu[i].t_ns)) {
      stream.addMeasurement(ranges[k++]);
    } else {
      stream.addImu(imu[i++]);
    }
    drain();
  }
  stream.finish();
  drain();
  if (stream.pendingStates() != 0 || stream.pendingRanges() != 0) {
    throw std::logic_error("buildRangeImuGraph: the stream kept states or ranges back");
  }

  for (const FactorPtr& f : imu_factors) out.graph.add(f);
  for (const FactorPtr& f : range_factors) out.graph.add(f);
  for (std::size_t a = 0; a < anchor_priors.size(); ++a) {
    if (!anchor_priors[a]) continue;
    out.graph.add(anchor_priors[a]);
    out.anchor_keys.push_back(sym::L(a));
  }
  for (const FactorPtr& f : motion_priors) out.graph.add(f);
  out.imu_factors = imu_factors.size();
  out.range_factors = range_factors.size();
  out.motion_priors = motion_priors.size();
  return out;
}

}  // namespace rilo
