#include "sim/office_scenario.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <stdexcept>
#include <string>

#include "sim/office_ultrasonic.h"

namespace rilo::sim {
namespace {

// Random streams of one simulation (office_random.h).
constexpr std::uint64_t kImuStream = 0x1a0;
constexpr std::uint64_t kRangeStream = 0x2a0;
constexpr std::uint64_t kChannelStream = 0x3a0;

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("OfficeScenarioParams.") + field + " " + what);
}

bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }

std::int64_t toNs(double t_s) { return static_cast<std::int64_t>(std::llround(t_s * 1e9)); }

}  // namespace

void validate(const OfficeScenarioParams& p) {
  require(std::isfinite(p.duration_s) && p.duration_s > 0.0 && p.duration_s <= 1e6, "duration_s", "must be in (0, 1e6] s");
  require(p.p_b_tag.allFinite() && p.p_b_tag.norm() < 1.0, "p_b_tag", "must be finite and within 1 m of the body origin");
  require(p.t0_ns >= 0 && p.t0_ns < std::numeric_limits<std::int64_t>::max() / 2, "t0_ns", "must be >= 0");
  require(std::isfinite(p.imu_rate_hz) && p.imu_rate_hz >= 10.0 && p.imu_rate_hz <= 10000.0, "imu_rate_hz",
          "must be in [10, 10000] Hz");
  require(std::isfinite(p.gravity_m_s2) && p.gravity_m_s2 > 0.0, "gravity_m_s2", "must be > 0");
  require(finiteNonNegative(p.gyro_noise_density), "gyro_noise_density", "must be >= 0");
  require(finiteNonNegative(p.accel_noise_density), "accel_noise_density", "must be >= 0");
  require(finiteNonNegative(p.gyro_bias_walk), "gyro_bias_walk", "must be >= 0");
  require(finiteNonNegative(p.accel_bias_walk), "accel_bias_walk", "must be >= 0");
  require(finiteNonNegative(p.gyro_bias_init_sigma), "gyro_bias_init_sigma", "must be >= 0");
  require(finiteNonNegative(p.accel_bias_init_sigma), "accel_bias_init_sigma", "must be >= 0");
  require(std::isfinite(p.range_rate_hz) && p.range_rate_hz > 0.0 && p.range_rate_hz <= 1000.0, "range_rate_hz",
          "must be in (0, 1000] Hz");
  require(p.ranges_per_cycle >= 1 && p.ranges_per_cycle <= 64, "ranges_per_cycle", "must be in [1, 64]");
  require(finiteNonNegative(p.range_sigma_m) && p.range_sigma_m <= 10.0, "range_sigma_m", "must be in [0, 10] m");
  require(std::isfinite(p.nlos_noise_factor) && p.nlos_noise_factor >= 1.0, "nlos_noise_factor", "must be >= 1");
  require(finiteNonNegative(p.anchor_bias_sigma_m) && p.anchor_bias_sigma_m <= 1.0, "anchor_bias_sigma_m",
          "must be in [0, 1] m");
  require(p.packet_loss >= 0.0 && p.packet_loss < 1.0, "packet_loss", "must be in [0, 1)");
  require(p.outlier_probability >= 0.0 && p.outlier_probability <= 1.0, "outlier_probability", "must be in [0, 1]");
  require(finiteNonNegative(p.outlier_scale_m), "outlier_scale_m", "must be >= 0");
  require(std::isfinite(p.outlier_max_m) && p.outlier_max_m >= 1.0, "outlier_max_m", "must be >= 1 m");
  require(p.early_outlier_fraction >= 0.0 && p.early_outlier_fraction <= 1.0, "early_outlier_fraction",
          "must be in [0, 1]");
  require(finiteNonNegative(p.selection_fading_db), "selection_fading_db", "must be >= 0");
  require(finiteNonNegative(p.rssi_fading_db), "rssi_fading_db", "must be >= 0");
  validate(p.channel);
  validate(p.tdoa);
  validate(p.ultrasonic);
  validate(p.hall);
}

OfficeSetup makeOfficeSetup(const OfficeScenarioParams& p) {
  validate(p);
  OfficeSetup s;
  auto plan = std::make_shared<OfficePlan>(officePlanOf(p));
  s.plan = plan;
  s.p_w_anchors = anchorsOf(*plan, p);
  WalkParams wp = p.walk;
  wp.seed = p.seed;
  wp.duration_s = p.duration_s + 1.0;
  s.walk = std::make_shared<OfficeWalk>(*plan, wp);
  s.channel = std::make_shared<OfficeChannel>(*plan, s.p_w_anchors, p.p_b_tag, p.channel,
                                              streamSeed(p.seed, kChannelStream));
  if (p.ultrasonic.enabled) s.p_w_ultrasonic = ultrasonicBeaconsOf(*plan, p);
  return s;
}

OfficePlan officePlanOf(const OfficeScenarioParams& p) {
  switch (p.plan) {
    case OfficePlanKind::kRandom: return randomOfficePlan(p.seed);
    case OfficePlanKind::kHall: return buildHallPlan(p.hall);
    case OfficePlanKind::kDefault: break;
  }
  return defaultOfficePlan();
}

std::vector<Eigen::Vector3d> anchorsOf(const OfficePlan& plan, const OfficeScenarioParams& p) {
  if (p.plan == OfficePlanKind::kHall) return placeHallAnchors(plan, p.hall, p.anchors.count, p.anchors.wall_offset_m);
  return placeAnchors(plan, p.anchors);
}

std::vector<Eigen::Vector3d> ultrasonicBeaconsOf(const OfficePlan& plan, const OfficeScenarioParams& p) {
  if (p.plan == OfficePlanKind::kHall) return placeHallUltrasonicBeacons(plan, p.ultrasonic);
  return placeUltrasonicBeacons(plan, p.ultrasonic);
}

ScenarioParams scenarioParamsOf(const OfficeScenarioParams& p) {
  ScenarioParams s;
  s.seed = p.seed;
  s.duration_s = p.duration_s;
  s.imu_rate_hz = p.imu_rate_hz;
  s.range_rate_hz = p.range_rate_hz;
  s.ranges_per_cycle = p.ranges_per_cycle;
  s.gravity_m_s2 = p.gravity_m_s2;
  s.gyro_noise_density = p.gyro_noise_density;
  s.accel_noise_density = p.accel_noise_density;
  s.gyro_bias_walk = p.gyro_bias_walk;
  s.accel_bias_walk = p.accel_bias_walk;
  s.gyro_bias_init_sigma = p.gyro_bias_init_sigma;
  s.accel_bias_init_sigma = p.accel_bias_init_sigma;
  s.range_sigma_m = p.range_sigma_m;
  s.nlos_fraction = std::numeric_limits<double>::quiet_NaN();
  s.nlos_mean_duration_s = std::numeric_limits<double>::quiet_NaN();
  s.nlos_scale_m = std::numeric_limits<double>::quiet_NaN();
  s.nlos_max_excess_m = p.channel.nlos_max_excess_m;
  s.outlier_probability = p.outlier_probability;
  s.range_dropout = p.packet_loss;
  return s;
}

// ---- IMU ------------------------------------------------------------------

OfficeImuStream::OfficeImuStream(const OfficeScenarioParams& p, std::shared_ptr<const Trajectory> truth)
    : p_(p), truth_(std::move(truth)), rng_(streamSeed(p.seed, kImuStream)) {
  validate(p_);
  count_ = static_cast<std::size_t>(std::floor(p_.duration_s * p_.imu_rate_hz)) + 1;
  b_g_ = p_.gyro_bias_init_sigma * rng_.normal3();
  b_a_ = p_.accel_bias_init_sigma * rng_.normal3();
  gyro_bias0_ = b_g_;
  accel_bias0_ = b_a_;
}

bool OfficeImuStream::next(ImuSample& sample, Eigen::Matrix<double, 6, 1>& bias) {
  if (k_ >= count_) return false;
  const double dt = 1.0 / p_.imu_rate_hz;
  const double t = static_cast<double>(k_) * dt;
  const ImuReading m = idealImu(truth_->at(t), p_.gravity_m_s2);
  sample.t_ns = p_.t0_ns + toNs(t);
  sample.gyro_rad_s = m.gyro + b_g_ + p_.gyro_noise_density / std::sqrt(dt) * rng_.normal3();
  sample.accel_m_s2 = m.accel + b_a_ + p_.accel_noise_density / std::sqrt(dt) * rng_.normal3();
  bias << b_a_, b_g_;
  b_g_ += p_.gyro_bias_walk * std::sqrt(dt) * rng_.normal3();
  b_a_ += p_.accel_bias_walk * std::sqrt(dt) * rng_.normal3();
  ++k_;
  return true;
}

// ---- Ranging --------------------------------------------------------------

std::vector<std::size_t> rankAnchors(const OfficeChannel& channel, const KinematicState& body,
                                     const std::vector<double>& fading_db) {
  std::vector<std::size_t> heard;
  std::vector<double> score(channel.anchorCount(), 0.0);
  for (std::size_t a = 0; a < channel.anchorCount(); ++a) {
    const LinkState L = channel.link(a, body);
    if (L.rssi_mean_dbm < channel.params().sensitivity_dbm) continue;
    score[a] = L.rssi_mean_dbm + (fading_db.empty() ? 0.0 : fading_db.at(a));
    heard.push_back(a);
  }
  std::stable_sort(heard.begin(), heard.end(), [&](std::size_t i, std::size_t j) { return score[i] > score[j]; });
  return heard;
}

OfficeRangeStream::OfficeRangeStream(const OfficeScenarioParams& p, const OfficeSetup& setup)
    : p_(p), setup_(setup), rng_(streamSeed(p.seed, kRangeStream)) {
  validate(p_);
  for (std::size_t a = 0; a < setup_.p_w_anchors.size(); ++a) anchor_bias_m_.push_back(p_.anchor_bias_sigma_m * rng_.normal());
  stats_.ranges_per_anchor.assign(setup_.p_w_anchors.size(), 0);
}

double OfficeRangeStream::progress() const {
  if (done_) return 1.0;
  return std::clamp(t_cycle_s_ / p_.duration_s, 0.0, 1.0);
}

bool OfficeRangeStream::next(RangeSample& sample, RangeTruth& truth) {
  const auto per_cycle = static_cast<std::size_t>(p_.ranges_per_cycle);
  const double slot_s = 1.0 / p_.range_rate_hz;
  while (!done_) {
    if (slot_ >= selected_.size()) {
      // New cycle: every slot must fall inside the session.
      t_cycle_s_ = static_cast<double>(cycle_) * static_cast<double>(per_cycle) * slot_s;
      if (t_cycle_s_ + static_cast<double>(per_cycle - 1) * slot_s > p_.duration_s) {
        done_ = true;
        break;
      }
      std::vector<double> fading(setup_.p_w_anchors.size());
      for (double& f : fading) f = p_.selection_fading_db * rng_.normal();
      selected_ = rankAnchors(*setup_.channel, setup_.walk->at(t_cycle_s_), fading);
      if (selected_.size() > per_cycle) selected_.resize(per_cycle);
      ++cycle_;
      ++stats_.cycles;
      stats_.slots += selected_.size();
      stats_.empty_slots += per_cycle - selected_.size();
      slot_ = 0;
      continue;
    }
    const std::size_t k = slot_++;
    const std::size_t a = selected_[k];
    if (rng_.bernoulli(p_.packet_loss)) {
      ++stats_.lost;
      continue;
    }
    const double t = t_cycle_s_ + static_cast<double>(k) * slot_s;
    const LinkState L = setup_.channel->link(a, setup_.walk->at(t));
    const double sigma = p_.range_sigma_m * (L.los ? 1.0 : p_.nlos_noise_factor);
    double error = L.excess_m + anchor_bias_m_[a] + sigma * rng_.normal();
    const bool outlier = rng_.bernoulli(p_.outlier_probability);
    if (outlier) {
      if (rng_.bernoulli(p_.early_outlier_fraction)) {
        error -= rng_.uniform(0.3, 1.5);  // a noise peak taken for the first path
      } else {
        error += std::min(p_.outlier_max_m, 1.0 + rng_.halfCauchy(p_.outlier_scale_m));
      }
    }
    const double rssi = L.rssi_mean_dbm + p_.rssi_fading_db * rng_.normal();
    const double gap = firstPathGapDb(L, rng_.normal());

    sample = RangeSample{};
    sample.t_ns = p_.t0_ns + toNs(t);
    sample.anchor_id = static_cast<std::uint32_t>(a);
    sample.tag_id = 0;
    sample.range_m = std::max(0.0, L.true_range_m + error);
    sample.rssi_dbm = rssi;
    sample.fp_power_dbm = p_.report_first_path ? rssi - gap : std::numeric_limits<double>::quiet_NaN();
    sample.los = L.los ? 1 : 0;

    truth = RangeTruth{};
    truth.true_range_m = L.true_range_m;
    truth.excess_m = L.excess_m;
    truth.error_m = sample.range_m - L.true_range_m;
    truth.obstruction = L.obstruction;
    truth.body_shadowed = L.body_shadowed;
    truth.outlier = outlier;
    truth.rssi_mean_dbm = L.rssi_mean_dbm;
    truth.cycle = cycle_ - 1;

    ++stats_.ranges;
    ++stats_.ranges_per_anchor[a];
    if (!L.los) {
      ++stats_.nlos;
      stats_.nlos_excess_sum_m += L.excess_m;
      stats_.nlos_excess_max_m = std::max(stats_.nlos_excess_max_m, L.excess_m);
    }
    if (outlier) ++stats_.outliers;
    return true;
  }
  return false;
}

// ---- Whole session ----------------------------------------------------------

OfficeSimulation simulateOffice(const OfficeScenarioParams& p) {
  OfficeSimulation sim;
  sim.setup = makeOfficeSetup(p);
  Scenario& s = sim.scenario;
  s.params = scenarioParamsOf(p);
  s.p_w_anchors = sim.setup.p_w_anchors;
  s.p_b_tag = p.p_b_tag;
  s.truth = sim.setup.walk;
  s.t0_ns = p.t0_ns;

  OfficeImuStream imu(p, sim.setup.walk);
  s.imu.reserve(imu.size());
  s.imu_bias_truth.reserve(imu.size());
  s.gyro_bias0 = imu.gyroBias0();
  s.accel_bias0 = imu.accelBias0();
  ImuSample m;
  Eigen::Matrix<double, 6, 1> b;
  while (imu.next(m, b)) {
    s.imu.push_back(m);
    s.imu_bias_truth.push_back(b);
  }

  OfficeRangeStream ranging(p, sim.setup);
  RangeSample r;
  RangeTruth rt;
  while (ranging.next(r, rt)) {
    s.ranges.push_back(r);
    sim.range_truth.push_back(rt);
  }
  sim.stats = ranging.stats();
  sim.stats.duration_s = p.duration_s;
  sim.stats.imu_samples = s.imu.size();
  s.params.nlos_fraction = sim.stats.nlosFraction();
  return sim;
}

}  // namespace rilo::sim
