#include "sim/range_imu_scenario.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>
#include <utility>

namespace rilo::sim {

std::vector<Eigen::Vector3d> defaultOfficeAnchors() {
  return {{-6.0, -5.0, 2.6}, {6.0, -5.0, 0.8}, {6.0, 5.0, 2.5}, {-6.0, 5.0, 0.9},
          {0.0, -5.5, 1.9},  {7.0, 0.0, 2.8},  {0.0, 5.5, 0.6}, {-7.0, 0.0, 2.2}};
}

Eigen::Matrix<double, 6, 1> Scenario::biasAt(std::int64_t t_ns) const {
  auto it = std::upper_bound(imu.begin(), imu.end(), t_ns,
                             [](std::int64_t t, const ImuSample& m) { return t < m.t_ns; });
  const std::size_t k = it == imu.begin() ? 0 : static_cast<std::size_t>(it - imu.begin()) - 1;
  return imu_bias_truth.at(k);
}

Scenario simulateScenario(const ScenarioParams& p) {
  return simulateScenario(p, std::make_shared<LissajousWalk>(), defaultOfficeAnchors());
}

Scenario simulateScenario(const ScenarioParams& p, std::shared_ptr<const Trajectory> truth,
                          std::vector<Eigen::Vector3d> p_w_anchors) {
  if (!truth) throw std::invalid_argument("simulateScenario: null trajectory");
  if (p_w_anchors.empty()) throw std::invalid_argument("simulateScenario: no anchors");
  Scenario s;
  s.params = p;
  s.p_w_anchors = std::move(p_w_anchors);
  s.p_b_tag = Eigen::Vector3d(0.05, 0.0, 0.08);
  s.truth = std::move(truth);
  s.t0_ns = 1'000'000'000;  // recordings rarely start at zero

  std::mt19937_64 rng(p.seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  auto randn3 = [&] { return Eigen::Vector3d(n01(rng), n01(rng), n01(rng)); };

  // IMU: white noise + random-walk biases, held constant over a sample.
  Eigen::Vector3d b_g = p.gyro_bias_init_sigma * randn3();
  Eigen::Vector3d b_a = p.accel_bias_init_sigma * randn3();
  s.gyro_bias0 = b_g;
  s.accel_bias0 = b_a;
  const double dt_imu = 1.0 / p.imu_rate_hz;
  const auto n_imu = static_cast<std::int64_t>(std::floor(p.duration_s * p.imu_rate_hz)) + 1;
  s.imu.reserve(static_cast<std::size_t>(n_imu));
  s.imu_bias_truth.reserve(static_cast<std::size_t>(n_imu));
  for (std::int64_t k = 0; k < n_imu; ++k) {
    const double t = static_cast<double>(k) * dt_imu;
    const ImuReading m = idealImu(s.truth->at(t), p.gravity_m_s2);
    ImuSample smp;
    smp.t_ns = s.t0_ns + static_cast<std::int64_t>(std::llround(t * 1e9));
    smp.gyro_rad_s = m.gyro + b_g + p.gyro_noise_density / std::sqrt(dt_imu) * randn3();
    smp.accel_m_s2 = m.accel + b_a + p.accel_noise_density / std::sqrt(dt_imu) * randn3();
    s.imu.push_back(smp);
    Eigen::Matrix<double, 6, 1> b;
    b << b_a, b_g;
    s.imu_bias_truth.push_back(b);
    b_g += p.gyro_bias_walk * std::sqrt(dt_imu) * randn3();
    b_a += p.accel_bias_walk * std::sqrt(dt_imu) * randn3();
  }

  // Ranging: a two-state Markov chain per anchor gives persistent NLOS.
  const std::size_t n_anchors = s.p_w_anchors.size();
  std::vector<bool> nlos(n_anchors, false);
  std::vector<double> nlos_bias(n_anchors, 0.0);
  const double dt_range = 1.0 / p.range_rate_hz;
  const double p_exit = std::min(1.0, dt_range * static_cast<double>(p.ranges_per_cycle) / p.nlos_mean_duration_s);
  const double p_enter = p_exit * p.nlos_fraction / std::max(1e-9, 1.0 - p.nlos_fraction);
  auto halfCauchy = [&](double scale) { return scale * std::abs(std::tan(M_PI * (u01(rng) - 0.5))); };

  const double cycle_s = dt_range * static_cast<double>(p.ranges_per_cycle);
  for (double t_cycle = 0.0; t_cycle + cycle_s <= p.duration_s; t_cycle += cycle_s) {
    // Markov step once per cycle; an NLOS episode keeps one excess (slowly varying).
    for (std::size_t a = 0; a < n_anchors; ++a) {
      if (nlos[a]) {
        if (u01(rng) < p_exit) nlos[a] = false;
        nlos_bias[a] = std::min(p.nlos_max_excess_m, std::max(0.0, nlos_bias[a] + 0.05 * n01(rng)));
      } else if (u01(rng) < p_enter) {
        nlos[a] = true;
        nlos_bias[a] = std::min(p.nlos_max_excess_m, halfCauchy(p.nlos_scale_m));
      }
    }
    // Strongest anchors: nearest, NLOS ones attenuated (counted as 3 m farther).
    const Eigen::Vector3d p_now = s.truth->at(t_cycle).T_w_b.p;
    std::vector<std::size_t> order(n_anchors);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](std::size_t i, std::size_t j) {
      const double di = (s.p_w_anchors[i] - p_now).norm() + (nlos[i] ? 3.0 : 0.0);
      const double dj = (s.p_w_anchors[j] - p_now).norm() + (nlos[j] ? 3.0 : 0.0);
      return di < dj;
    });
    for (int k = 0; k < p.ranges_per_cycle && static_cast<std::size_t>(k) < n_anchors; ++k) {
      const double t = t_cycle + static_cast<double>(k) * dt_range;
      if (u01(rng) < p.range_dropout) continue;
      const std::size_t a = order[static_cast<std::size_t>(k)];
      const KinematicState st = s.truth->at(t);
      const double true_range = (st.T_w_b.transformFrom(s.p_b_tag) - s.p_w_anchors[a]).norm();
      double excess = p.range_sigma_m * n01(rng);
      if (nlos[a]) excess += nlos_bias[a];
      if (u01(rng) < p.outlier_probability) excess += std::min(p.nlos_max_excess_m, halfCauchy(1.5));
      RangeSample r;
      r.t_ns = s.t0_ns + static_cast<std::int64_t>(std::llround(t * 1e9));
      r.anchor_id = static_cast<std::uint32_t>(a);
      r.range_m = std::max(0.0, true_range + excess);
      r.rssi_dbm = std::nan("");
      r.los = nlos[a] ? 0 : 1;
      s.ranges.push_back(r);
    }
  }
  return s;
}

ImuParams imuParamsOf(const ScenarioParams& p) {
  ImuParams imu;
  imu.gravity_m_s2 = p.gravity_m_s2;
  imu.gyro_noise_density = p.gyro_noise_density;
  imu.accel_noise_density = p.accel_noise_density;
  imu.gyro_bias_random_walk = p.gyro_bias_walk;
  imu.accel_bias_random_walk = p.accel_bias_walk;
  imu.gyro_bias_tau_s = ImuParams::kRandomWalk;
  imu.accel_bias_tau_s = ImuParams::kRandomWalk;
  return imu;
}

Values truthValues(const Scenario& s, const std::vector<std::int64_t>& state_t_ns, const std::vector<Key>& anchor_keys,
                   const TruthPerturbation* perturbation) {
  std::mt19937_64 rng(perturbation ? perturbation->seed : 0);
  std::normal_distribution<double> n01(0.0, 1.0);
  auto randn3 = [&] { return Vec3(n01(rng), n01(rng), n01(rng)); };
  Values v;
  for (std::size_t i = 0; i < state_t_ns.size(); ++i) {
    const KinematicState st = s.truthAt(state_t_ns[i]);
    if (perturbation) {
      Vec6 xi;
      xi << perturbation->rotation_rad * randn3(), perturbation->position_m * randn3();
      v.insert(sym::X(i), st.T_w_b.retract(xi));
      v.insert(sym::V(i), Vec3(st.v_w + perturbation->velocity_m_s * randn3()));
      v.insert(sym::B(i), ImuBias());
    } else {
      v.insert(sym::X(i), st.T_w_b);
      v.insert(sym::V(i), st.v_w);
      v.insert(sym::B(i), ImuBias(s.biasAt(state_t_ns[i])));
    }
  }
  for (Key l : anchor_keys) v.insert(l, s.p_w_anchors.at(keyIndex(l)));
  return v;
}

}  // namespace rilo::sim
