#include "sim/office_tdoa.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo::sim {
namespace {

// Random stream of the TDoA measurements (office_random.h; the office
// scenario uses 0x1a0 IMU, 0x2a0 ranging, 0x3a0 channel fields).
constexpr std::uint64_t kTdoaStream = 0x4a0;
// The receive diagnostics have their own stream, so adding them left the
// TDoA values of a seed as they were.
constexpr std::uint64_t kTdoaDiagnosticsStream = 0x5a0;

void require(bool ok, const char* field, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("TdoaParams.") + field + " " + what);
}

bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }

std::int64_t toNs(double t_s) { return static_cast<std::int64_t>(std::llround(t_s * 1e9)); }

}  // namespace

void validate(const TdoaParams& p) {
  require(std::isfinite(p.round_rate_hz) && p.round_rate_hz > 0.0 && p.round_rate_hz <= 200.0, "round_rate_hz",
          "must be in (0, 200] Hz");
  require(p.packet_reception > 0.0 && p.packet_reception <= 1.0, "packet_reception", "must be in (0, 1]");
  require(finiteNonNegative(p.sigma_m) && p.sigma_m <= 10.0, "sigma_m", "must be in [0, 10] m");
  require(std::isfinite(p.nlos_noise_factor) && p.nlos_noise_factor >= 1.0, "nlos_noise_factor", "must be >= 1");
  require(finiteNonNegative(p.anchor_bias_sigma_m) && p.anchor_bias_sigma_m <= 1.0, "anchor_bias_sigma_m",
          "must be in [0, 1] m");
  require(p.outlier_probability >= 0.0 && p.outlier_probability <= 1.0, "outlier_probability", "must be in [0, 1]");
  require(finiteNonNegative(p.outlier_scale_m), "outlier_scale_m", "must be >= 0");
  require(std::isfinite(p.outlier_max_m) && p.outlier_max_m >= 1.0, "outlier_max_m", "must be >= 1 m");
  require(p.early_outlier_fraction >= 0.0 && p.early_outlier_fraction <= 1.0, "early_outlier_fraction",
          "must be in [0, 1]");
  require(finiteNonNegative(p.hearing_fading_db), "hearing_fading_db", "must be >= 0");
  require(finiteNonNegative(p.max_reference_age_s) && p.max_reference_age_s <= 10.0, "max_reference_age_s",
          "must be in [0, 10] s");
}

double anchorToAnchorRssiDbm(const OfficePlan& plan, const ChannelParams& c, const Eigen::Vector3d& p_w_a,
                             const Eigen::Vector3d& p_w_b) {
  const Obstruction o = obstruction(plan, p_w_a, p_w_b);
  const double loss_db = o.drywall * c.drywall.loss_db + o.concrete * c.concrete.loss_db + o.desks * c.desk.loss_db +
                         o.cabinets * c.cabinet.loss_db + o.people * c.person.loss_db + o.pillars * c.pillar.loss_db;
  const double d = std::max((p_w_a - p_w_b).norm(), 0.1);
  return c.rssi_1m_dbm - 10.0 * c.path_loss_exponent * std::log10(d) - loss_db;
}

OfficeTdoaStream::OfficeTdoaStream(const OfficeScenarioParams& p, const OfficeSetup& setup)
    : tp_(p.tdoa),
      duration_s_(p.duration_s),
      t0_ns_(p.t0_ns),
      setup_(setup),
      anchors_(setup.p_w_anchors.size()),
      rng_(streamSeed(p.seed, kTdoaStream)),
      diagnostics_rng_(streamSeed(p.seed, kTdoaDiagnosticsStream)) {
  validate(p);
  if (anchors_ < 2) throw std::invalid_argument("OfficeTdoaStream: TDoA needs at least 2 UWB anchors");
  if (!setup_.channel || !setup_.walk || !setup_.plan) throw std::invalid_argument("OfficeTdoaStream: incomplete setup");
  for (std::size_t a = 0; a < anchors_; ++a) bias_m_.push_back(tp_.anchor_bias_sigma_m * rng_.normal());
  const ChannelParams& c = setup_.channel->params();
  audible_.assign(anchors_ * anchors_, 0);
  for (std::size_t a = 0; a < anchors_; ++a) {
    for (std::size_t b = 0; b < anchors_; ++b) {
      if (a == b) continue;
      const double level = anchorToAnchorRssiDbm(*setup_.plan, c, setup_.p_w_anchors[a], setup_.p_w_anchors[b]);
      audible_[a * anchors_ + b] = level >= c.sensitivity_dbm ? 1 : 0;
    }
  }
  last_rx_s_.assign(anchors_, -std::numeric_limits<double>::infinity());
  last_rssi_dbm_.assign(anchors_, 0.0);
  last_gap_db_.assign(anchors_, 0.0);
  stats_.duration_s = duration_s_;
  stats_.measurements_per_anchor.assign(anchors_, 0);
}

double OfficeTdoaStream::progress() const {
  if (done_) return 1.0;
  return std::clamp(t_s_ / duration_s_, 0.0, 1.0);
}

bool OfficeTdoaStream::next(TdoaSample& sample, TdoaTruth& truth) {
  const double slot_s = 1.0 / (tp_.round_rate_hz * static_cast<double>(anchors_));
  const double max_age_s = tp_.max_reference_age_s > 0.0 ? tp_.max_reference_age_s : 1.0 / tp_.round_rate_hz;
  const double sensitivity_dbm = setup_.channel->params().sensitivity_dbm;
  while (!done_) {
    const double t = static_cast<double>(slot_) * slot_s;
    if (t > duration_s_) {
      done_ = true;
      break;
    }
    t_s_ = t;
    const std::size_t b = slot_ % anchors_;
    ++slot_;
    if (b == 0) ++stats_.rounds;
    ++stats_.packets;
    // Both draws every slot, so one slot's outcome does not shift the next slot's draws.
    const double fading_db = tp_.hearing_fading_db * rng_.normal();
    const bool received = rng_.bernoulli(tp_.packet_reception);
    const KinematicState body = setup_.walk->at(t);
    const LinkState link_b = setup_.channel->link(b, body);
    if (link_b.rssi_mean_dbm + fading_db < sensitivity_dbm) continue;
    ++stats_.heard;
    if (!received) continue;
    ++stats_.received;

    // Reference: the latest received packet of another anchor that b hears.
    std::size_t a = anchors_;
    double t_a = -std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < anchors_; ++k) {
      if (k == b || !audible_[k * anchors_ + b]) continue;
      if (last_rx_s_[k] > t_a && t - last_rx_s_[k] <= max_age_s + 1e-9) {
        a = k;
        t_a = last_rx_s_[k];
      }
    }
    last_rx_s_[b] = t;
    last_rssi_dbm_[b] = link_b.rssi_mean_dbm + fading_db;
    last_gap_db_[b] = firstPathGapDb(link_b, diagnostics_rng_.normal());
    if (a == anchors_) {
      ++stats_.no_reference;
      continue;
    }

    const LinkState link_a = setup_.channel->link(a, body);
    const bool los = link_a.los && link_b.los;
    const double sigma = tp_.sigma_m * (los ? 1.0 : tp_.nlos_noise_factor);
    const double bias = bias_m_[b] - bias_m_[a];
    double error = link_b.excess_m - link_a.excess_m + bias + sigma * rng_.normal();
    const bool outlier = rng_.bernoulli(tp_.outlier_probability);
    bool outlier_on_b = false;
    if (outlier) {
      outlier_on_b = rng_.bernoulli(0.5);
      const double path_error = rng_.bernoulli(tp_.early_outlier_fraction)
                                    ? -rng_.uniform(0.3, 1.5)  // a noise peak taken for the first path
                                    : std::min(tp_.outlier_max_m, 1.0 + rng_.halfCauchy(tp_.outlier_scale_m));
      error += outlier_on_b ? path_error : -path_error;
    }
    const double true_diff = link_b.true_range_m - link_a.true_range_m;

    sample = TdoaSample{};
    sample.t_ns = t0_ns_ + toNs(t);
    sample.anchor_a = static_cast<std::uint32_t>(a);
    sample.anchor_b = static_cast<std::uint32_t>(b);
    sample.diff_m = true_diff + error;
    sample.rssi_a_dbm = last_rssi_dbm_[a];  // the reference packet's, as received at t_a
    sample.fp_power_a_dbm = last_rssi_dbm_[a] - last_gap_db_[a];
    sample.rssi_b_dbm = last_rssi_dbm_[b];
    sample.fp_power_b_dbm = last_rssi_dbm_[b] - last_gap_db_[b];
    sample.los = los ? 1 : 0;

    truth = TdoaTruth{};
    truth.true_diff_m = true_diff;
    truth.error_m = sample.diff_m - true_diff;
    truth.excess_a_m = link_a.excess_m;
    truth.excess_b_m = link_b.excess_m;
    truth.bias_m = bias;
    truth.los_a = link_a.los;
    truth.los_b = link_b.los;
    truth.outlier = outlier;
    truth.outlier_on_b = outlier_on_b;
    truth.reference_age_s = t - t_a;

    ++stats_.measurements;
    ++stats_.measurements_per_anchor[b];
    if (!los) {
      ++stats_.nlos;
      if (link_a.los) ++stats_.nlos_b_only;
      if (link_b.los) ++stats_.nlos_a_only;
      const double nlos_bias = std::abs(link_b.excess_m - link_a.excess_m);
      stats_.nlos_bias_abs_sum_m += nlos_bias;
      stats_.nlos_bias_abs_max_m = std::max(stats_.nlos_bias_abs_max_m, nlos_bias);
      for (const LinkState* l : {&link_a, &link_b}) {
        if (l->los) continue;
        ++stats_.nlos_paths;
        stats_.nlos_path_excess_sum_m += l->excess_m;
      }
    }
    if (outlier) ++stats_.outliers;
    return true;
  }
  return false;
}

}  // namespace rilo::sim
