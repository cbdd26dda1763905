// The initializer's batch solve (the Ranging-IMU Fusion paper, Sec. V): Levenberg-Marquardt over
// the aligned window's range + IMU graph, the gates a start must pass (range
// and IMU cost, predicted and solved uncertainty, height band, anchors' box,
// short ranges), and the state and covariance handed to tracking. The attempt
// that builds the window is initializer.cpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include "estimation/factors/prior_factors.h"
#include "estimation/factors/range_factor.h"
#include "estimation/factors/tdoa_factor.h"
#include "estimation/init/format.h"
#include "estimation/init/initializer.h"
#include "estimation/init/window_time.h"
#include "estimation/noise/noise_model_factory.h"
#include "estimation/solver/batch_lm.h"

namespace rilo {

using init_detail::imuIndexAt;
using init_detail::strprintf;
using init_detail::toNs;
using init_detail::toS;

namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
constexpr double kTdoaGateCostCap = 0.5 * 3.0 * 3.0;  ///< cost of a 3-sigma residual (batchCosts)

/// Zero-velocity priors on the window's states inside still intervals, each
/// sigma * sqrt(1 s / the time the state stands for); returns the still time (s).
double addStillPriors(const std::vector<StillInterval>& still, double sigma_m_s, RangeImuGraph& graph) {
  const std::vector<std::int64_t>& ts = graph.state_t_ns;
  std::size_t k = 0;
  for (std::size_t i = 0; i < ts.size(); ++i) {
    while (k < still.size() && still[k].t1_ns <= ts[i]) ++k;
    if (k == still.size() || ts[i] < still[k].t0_ns) continue;
    // The time this state stands for: half the intervals to its neighbours.
    const std::int64_t before = i > 0 ? ts[i] - ts[i - 1] : 0, after = i + 1 < ts.size() ? ts[i + 1] - ts[i] : 0;
    const double dt_s = std::max(1e-3, 0.5 * toS(before + after));
    const Vec3 sigmas = Vec3::Constant(sigma_m_s * std::sqrt(1.0 / dt_s));
    graph.graph.emplace<PriorVec3Factor>(sym::V(i), Vec3(Vec3::Zero()), sigmas);
  }
  double still_s = 0.0;
  for (const StillInterval& iv : still) still_s += toS(iv.t1_ns - iv.t0_ns);
  return still_s;
}

/// What the batch's gates judge of a solution: the IMU and measurement costs,
/// the measurements' whitened residuals, and the two-way ranges far shorter
/// than the solution predicts (heavyNlosFactor).
struct BatchCosts {
  double imu_cost = 0.0;
  double range_cost = 0.0;
  std::vector<double> abs_residuals;
  int ranges = 0;
  int short_ranges = 0;
};

BatchCosts batchCosts(const RangeImuGraph& g, const Values& values) {
  // Factor layout of buildRangeImuGraph: 3 first-state priors, the IMU
  // factors, the measurement factors, anchor priors, motion priors.
  const std::size_t first_imu = 3, first_range = 3 + g.imu_factors;
  BatchCosts c;
  for (std::size_t k = first_imu; k < first_range; ++k) c.imu_cost += g.graph[k]->error(values);
  // One evaluation per measurement factor: its cost and its whitened
  // residuals (the residual scale, for the hand-over covariance).
  c.abs_residuals.reserve(g.range_factors);
  for (std::size_t k = first_range; k < first_range + g.range_factors; ++k) {
    const Factor& f = *g.graph[k];
    Residual r;
    f.evaluate(values, r, nullptr);
    for (Eigen::Index j = 0; j < r.size(); ++j) c.abs_residuals.push_back(std::abs(r(j)));
    // TDoA's default loss (Huber) grows without bound: in a hall where most
    // rows have a blocked path, the mean would measure the NLOS share, not
    // the fit. Capped at a 3-sigma residual's cost, the mean says how many
    // rows the solution explains. (The range and ultrasonic losses have heavy
    // NLOS tails already.)
    const double e = f.errorOfResidual(r);
    c.range_cost += dynamic_cast<const TdoaFactor*>(&f) ? std::min(e, kTdoaGateCostCap) : e;
    if (dynamic_cast<const RangeFactor*>(&f)) {
      ++c.ranges;
      if (r(0) < -kShortRangeSigmas) ++c.short_ranges;  // (measured - predicted) / sigma
    }
  }
  return c;
}

/// The hand-over state: the newest one that at least
/// hand_over_later_measurements of the window's measurements follow (the
/// newest with 0) when ranging is sparse. See the parameter for why.
std::size_t handOverStateIndex(const std::vector<Measurement>& range_vec, const std::vector<std::int64_t>& state_t_ns,
                               const InitializerParams& P) {
  std::size_t h = state_t_ns.size() - 1;
  const std::size_t k_later = static_cast<std::size_t>(P.hand_over_later_measurements);
  const bool sparse = k_later > 0 && range_vec.size() > k_later &&
                      range_vec.back().t_ns - range_vec[range_vec.size() - k_later].t_ns > toNs(P.hand_over_sparse_span_s);
  if (sparse) {
    std::size_t later = 0, k = range_vec.size();
    while (h > 0) {
      while (k > 0 && range_vec[k - 1].t_ns > state_t_ns[h]) {
        --k;
        ++later;
      }
      if (later >= k_later) break;
      --h;
    }
  }
  return h;
}

}  // namespace

bool Initializer::solveBatch(const AlignedWindow& w, std::int64_t t_now) {
  const InitializerParams& P = params_;
  const AlignmentResult& align = w.alignment;
  const std::int64_t t_w0 = align.t_ref_ns;
  const std::size_t i0 = imuIndexAt(imu_, t_w0);
  const std::span<const ImuSample> imu(imu_.data() + i0, imu_.size() - i0);

  // 4. The Ranging-IMU Fusion paper's batch over the window, every state started on the aligned track.
  const std::vector<ImuSample> imu_vec(imu.begin(), imu.end());
  std::vector<Measurement> range_vec;
  range_vec.reserve(w.end - w.begin);
  for (std::size_t k = w.begin; k < w.end; ++k) {
    if (meas_[k].t_ns >= imu_vec.front().t_ns && meas_[k].t_ns <= imu_vec.back().t_ns) range_vec.push_back(meas_[k]);
  }
  if (range_vec.empty()) {
    setStatus(InitState::kWaitingForData, "waiting: no ranges inside the IMU's time span");
    return false;
  }
  const std::int64_t t_graph0 = range_vec.front().t_ns;
  const StrapdownState s0 = align.at(integrateStrapdown(imu, t_w0, {t_graph0}).front(), P.graph.imu.gravity_m_s2);
  InitWindow win;
  RangeImuGraphParams graph_params = P.graph;
  if (P.tdoa_state_window_ns > 0 && std::any_of(range_vec.begin(), range_vec.end(), [](const Measurement& m) {
        return m.kind == Measurement::Kind::kTdoa;
      })) {
    graph_params.same_state_window_ns = P.tdoa_state_window_ns;
  }
  win.graph = buildRangeImuGraph(imu_vec, range_vec, p_w_anchors_, s0.T_w_b, s0.v_w, graph_params);
  const std::vector<StrapdownDelta> deltas = integrateStrapdown(imu, t_w0, win.graph.state_t_ns);
  Values initial;
  for (std::size_t i = 0; i < deltas.size(); ++i) {
    const StrapdownState st = align.at(deltas[i], P.graph.imu.gravity_m_s2);
    initial.insert(sym::X(i), st.T_w_b);
    initial.insert(sym::V(i), st.v_w);
    initial.insert(sym::B(i), align.bias);
  }
  for (Key l : win.graph.anchor_keys) initial.insert(l, p_w_anchors_.at(keyIndex(l)));
  const double still_s = std::isfinite(P.zero_velocity_sigma_m_s)
                             ? addStillPriors(findStillIntervals(imu, t_graph0, t_now, P.gravity),
                                              P.zero_velocity_sigma_m_s, win.graph)
                             : 0.0;

  const std::size_t n_states = win.graph.state_t_ns.size();
  const Key x_last = sym::X(n_states - 1);
  // The gate: the newest state's marginal sigmas at the starting values (one
  // factorization, no iterations) predict those at the solution (measured on
  // the 7 sims: within 0.5 deg of yaw, 8 %). Well above what acceptance
  // allows, the solve would be rejected: skip it, unless batch_gate_max_s of
  // data passed since the last solve that ran (or since the first attempt
  // that got this far).
  if (!batch_stage_reached_) {
    batch_stage_reached_ = true;
    last_batch_ns_ = t_now;
  }
  // One solver for the probe and the solve: the solve reuses the probe's
  // ordering, symbolic factorization and linearization at the start.
  BatchLevenbergMarquardt lm(P.lm);
  if (std::isfinite(P.batch_gate_sigma_factor) && t_now - last_batch_ns_ < toNs(P.batch_gate_max_s)) {
    const std::optional<CovarianceBlock> cov0 = lm.covarianceAt(win.graph.graph, initial, x_last);
    if (cov0 && cov0->rows() == 6) {
      const Pose3& T0 = initial.pose(x_last);
      const double pos0 = std::sqrt(std::max(0.0, cov0->bottomRightCorner<3, 3>().trace()));
      const Mat3 cov_rot_w = T0.R * cov0->topLeftCorner<3, 3>() * T0.R.transpose();
      const double yaw0 = std::sqrt(std::max(0.0, cov_rot_w(2, 2)));
      if (pos0 > P.batch_gate_sigma_factor * P.max_position_sigma_m ||
          yaw0 > P.batch_gate_sigma_factor * P.max_yaw_sigma_rad) {
        ++status_.gated_solves;
        setStatus(InitState::kBatchRejected,
                  strprintf("waiting: state not determined well enough yet (predicted before solving: sigma %.2f m, "
                            "yaw sigma %.1f deg)", pos0, yaw0 * kRadToDeg));
        return false;
      }
    }
  }
  const std::int64_t previous_batch_ns = last_batch_ns_;
  ++status_.batch_solves;
  last_batch_ns_ = t_now;
  BatchLevenbergMarquardt::Output out = lm.optimize(win.graph.graph, initial);
  if (out.result.status == LmStatus::kCancelled) {  // attempt() says why; the gate's clock is not reset
    --status_.batch_solves;
    last_batch_ns_ = previous_batch_ns;
    return false;
  }
  BatchCosts costs = batchCosts(win.graph, out.values);  // residualScale reorders the residuals
  const int ranges = costs.ranges, short_ranges = costs.short_ranges;
  const double residual_scale = residualScale(costs.abs_residuals);
  const double range_cpr = costs.range_cost / static_cast<double>(std::max<std::size_t>(1, win.graph.range_factors));
  const double imu_cpf = costs.imu_cost / static_cast<double>(std::max<std::size_t>(1, win.graph.imu_factors));
  const Pose3 T_last = out.values.pose(x_last);
  std::string reject;
  if (!out.result.converged()) {
    reject = std::string("not converged (") + toString(out.result.status) + ")";
  }
  const double batch_factor = heavyNlosFactor(t_now, ranges, short_ranges, static_cast<int>(win.graph.range_factors));
  if (reject.empty() &&
      (range_cpr > batch_factor * P.max_range_cost_per_range || imu_cpf > P.max_imu_cost_per_factor)) {
    reject = "cost too high";
  }
  // Passed (or judged) at a widened gate: said on the start and on a rejection.
  const bool heavy_nlos = w.heavy_nlos || (batch_factor > 1.0 && range_cpr > P.max_range_cost_per_range);
  // The marginal covariance (a factorization and a selected inverse) only
  // once the solve converged with plausible costs: a rejected solve does not
  // pay for it. The checks keep their order, so the same solves are accepted.
  std::optional<CovarianceBlock> cov;
  double pos_sigma = std::numeric_limits<double>::infinity(), yaw_sigma = pos_sigma;
  if (reject.empty()) {
    std::string cov_failure;
    cov = lm.marginalCovariance(x_last, &cov_failure);
    if (cov && cov->rows() == 6) {
      pos_sigma = std::sqrt(std::max(0.0, cov->bottomRightCorner<3, 3>().trace()));
      // World yaw: the right perturbation phi of R is R phi in the world frame.
      const Mat3 cov_rot_w = T_last.R * cov->topLeftCorner<3, 3>() * T_last.R.transpose();
      yaw_sigma = std::sqrt(std::max(0.0, cov_rot_w(2, 2)));
    }
    if (!cov) reject = "covariance unavailable (" + cov_failure + ")";
  }
  const Vec3 tag_last = T_last.transformFrom(P.graph.p_b_tag);
  std::string summary =
      strprintf("batch over %.1f s (%zu states): ", toS(win.graph.state_t_ns.back() - t_graph0), n_states) +
      strprintf("range cost %.2f, IMU cost %.3g per factor, residual scale %.2f, ", range_cpr, imu_cpf, residual_scale);
  summary += cov ? strprintf("sigma %.2f m, yaw sigma %.1f deg", pos_sigma, yaw_sigma * kRadToDeg)
                 : std::string("sigmas not computed");
  if (ranges > 0) summary += strprintf(", %d of %d ranges short", short_ranges, ranges);
  if (heavy_nlos) summary += " (heavy NLOS: cost gates widened)";
  if (!reject.empty()) {
    // Already rejected above.
  } else if (!(pos_sigma <= P.max_position_sigma_m) || !(yaw_sigma <= P.max_yaw_sigma_rad)) {
    reject = "state not determined well enough yet";
  } else if (!P.height_band.contains(tag_last.z(), 3.0 * P.height_band.sigma_m)) {
    reject = strprintf("tag height %.2f m outside the height band", tag_last.z());
  } else if (const double out_m = anchor_box_.outside(tag_last); !(out_m <= P.max_outside_anchors_m)) {
    reject = strprintf("tag %.1f m outside the anchors' horizontal box (limit %.1f)", out_m, P.max_outside_anchors_m);
  }
  if (!reject.empty()) {
    setStatus(InitState::kBatchRejected, "waiting: " + reject + "; " + summary);
    return false;
  }

  const std::size_t h = handOverStateIndex(range_vec, win.graph.state_t_ns, P);
  InitResult res;
  res.state.index = h;
  res.state.t_ns = win.graph.state_t_ns[h];
  res.state.T_w_b = out.values.pose(sym::X(h));
  res.state.v_w = out.values.vec3(sym::V(h));
  res.state.bias = out.values.bias(sym::B(h));
  if (h != n_states - 1) {
    const std::optional<CovarianceBlock> cov_h = lm.marginalCovariance(sym::X(h));
    if (cov_h && cov_h->rows() == 6) cov = cov_h;
  }
  res.pose_covariance = *cov;
  if (P.hand_over_covariance) {
    // The tracker starts from these (handOver); without them it falls back to the loose defaults.
    const std::optional<CovarianceBlock> cov_v = lm.marginalCovariance(sym::V(h));
    const std::optional<CovarianceBlock> cov_b = lm.marginalCovariance(sym::B(h));
    if (cov_v && cov_b && cov_v->rows() == 3 && cov_b->rows() == 6) {
      const double s = std::clamp(std::isfinite(residual_scale) ? residual_scale : 1.0, 1.0,
                                  P.max_hand_over_residual_scale);
      res.start_covariance =
          conditionStartCovariance(Mat6(*cov), Mat3(*cov_v), Mat6(*cov_b), P.hand_over_conditioning, s * s);
    }
  }
  res.data_start_ns = data_start_ns_;
  res.window_start_ns = t_graph0;
  res.time_to_init_s = toS(t_now - data_start_ns_);
  res.fix = w.fix;
  res.fix_from_tdoa = w.fix_from_tdoa;
  res.gravity = w.gravity;
  res.alignment = align;
  res.lm = out.result;
  res.range_cost_per_range = range_cpr;
  res.heavy_nlos = heavy_nlos;
  res.residual_scale = residual_scale;
  res.imu_cost_per_factor = imu_cpf;
  res.still_s = still_s;
  if (P.keep_window) {
    win.values = std::move(out.values);
    res.window = std::move(win);
  }
  result_ = std::move(res);
  setStatus(InitState::kInitialized, strprintf("initialized after %.1f s of data; ", result_->time_to_init_s) + summary);
  return true;
}

}  // namespace rilo
