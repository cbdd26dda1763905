#include "sim/office_ultrasonic.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

namespace rilo::sim {
namespace {

// Random streams of the ultrasonic measurements (office_random.h; the office
// scenario uses 0x1a0-0x3a0, TDoA 0x4a0).
constexpr std::uint64_t kUltrasonicStream = 0x5a0;
constexpr std::uint64_t kUltrasonicFieldStream = 0x5b0;

// Echo time margin of the ping schedule (m of travel): noise and rounding.
constexpr double kEchoMarginM = 0.25;

void require(bool ok, const char* field, const std::string& what) {
  if (!ok) throw std::invalid_argument(std::string("UltrasonicParams.") + field + (what.starts_with(':') ? "" : " ") + what);
}

bool finiteNonNegative(double x) { return std::isfinite(x) && x >= 0.0; }

std::int64_t toNs(double t_s) { return static_cast<std::int64_t>(std::llround(t_s * 1e9)); }

}  // namespace

void validate(const UltrasonicParams& p) {
  require(p.beacons >= 1 && p.beacons <= 64, "beacons", "must be in [1, 64]");
  require(std::isfinite(p.ping_rate_hz) && p.ping_rate_hz > 0.0 && p.ping_rate_hz <= 100.0, "ping_rate_hz",
          "must be in (0, 100] Hz");
  require(std::isfinite(p.max_range_m) && p.max_range_m >= 0.5 && p.max_range_m <= 50.0, "max_range_m",
          "must be in [0.5, 50] m");
  require(finiteNonNegative(p.sigma_m) && p.sigma_m <= 1.0, "sigma_m", "must be in [0, 1] m");
  require(std::isfinite(p.speed_of_sound_m_s) && p.speed_of_sound_m_s >= 300.0 && p.speed_of_sound_m_s <= 400.0,
          "speed_of_sound_m_s", "must be in [300, 400] m/s");
  require(std::isfinite(p.speed_of_sound_scale_error) && std::abs(p.speed_of_sound_scale_error) <= 0.1,
          "speed_of_sound_scale_error", "must be in [-0.1, 0.1]");
  require(p.reflection_probability >= 0.0 && p.reflection_probability <= 1.0, "reflection_probability",
          "must be in [0, 1]");
  require(finiteNonNegative(p.reflection_min_m), "reflection_min_m", "must be >= 0");
  require(finiteNonNegative(p.reflection_scale_m), "reflection_scale_m", "must be >= 0");
  require(std::isfinite(p.reflection_max_m) && p.reflection_max_m >= p.reflection_min_m, "reflection_max_m",
          "must be >= reflection_min_m");
  require(p.dropout >= 0.0 && p.dropout < 1.0, "dropout", "must be in [0, 1)");
  require(p.mount_below_ceiling_m >= 0.0 && p.mount_below_ceiling_m <= 1.0, "mount_below_ceiling_m",
          "must be in [0, 1] m");
  require(p.p_b_receiver.allFinite() && p.p_b_receiver.norm() < 1.0, "p_b_receiver",
          "must be finite and within 1 m of the body origin");
  require(p.field_length_m > 0.05 && p.field_length_m <= 100.0, "field_length_m", "must be in (0.05, 100] m");
  // Each ping's echo window must end before the next beacon pings.
  const double slot_s = 1.0 / (p.ping_rate_hz * static_cast<double>(p.beacons));
  const double echo_s = (p.max_range_m + kEchoMarginM) / p.speed_of_sound_m_s;
  if (slot_s < echo_s) {
    char what[256];
    std::snprintf(what, sizeof(what),
                  ": %d beacons at %g Hz leave %.1f ms per ping, less than the %.1f ms sound needs for max_range_m "
                  "%g m; lower the rate, the beacons or max_range_m",
                  p.beacons, p.ping_rate_hz, 1e3 * slot_s, 1e3 * echo_s, p.max_range_m);
    require(false, "ping_rate_hz", what);
  }
}

std::vector<Eigen::Vector3d> placeUltrasonicBeacons(const OfficePlan& plan, const UltrasonicParams& params) {
  validate(params);
  if (!(plan.ceiling_m - params.mount_below_ceiling_m > 2.0)) {
    throw std::invalid_argument("placeUltrasonicBeacons: beacons would hang below 2 m (ceiling too low)");
  }
  struct Candidate {
    Eigen::Vector2d p;
    int space;
    bool used = false;
  };
  constexpr double kSpacingM = 6.0;
  std::vector<Candidate> candidates;
  for (std::size_t si = 0; si < plan.spaces.size(); ++si) {
    const Space& s = plan.spaces[si];
    const Eigen::Vector2d size = s.free_max_w - s.free_min_w;
    const Eigen::Vector2d mid = 0.5 * (s.free_min_w + s.free_max_w);
    const int axis = size.x() >= size.y() ? 0 : 1;
    const int n = std::max(1, static_cast<int>(std::lround(size(axis) / kSpacingM)));
    for (int i = 0; i < n; ++i) {
      Eigen::Vector2d p = mid;
      p(axis) = s.free_min_w(axis) + size(axis) * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
      candidates.push_back({p, static_cast<int>(si)});
    }
  }
  if (static_cast<std::size_t>(params.beacons) > candidates.size()) {
    throw std::invalid_argument("UltrasonicParams.beacons " + std::to_string(params.beacons) + " exceeds the " +
                                std::to_string(candidates.size()) + " ceiling mounting points of this plan");
  }
  std::vector<int> per_space(plan.spaces.size(), 0);
  std::vector<Eigen::Vector2d> chosen;
  const Eigen::Vector2d centre = 0.5 * plan.size_m;
  for (int i = 0; i < params.beacons; ++i) {
    int least = std::numeric_limits<int>::max();
    for (const Candidate& c : candidates) {
      if (!c.used) least = std::min(least, per_space[static_cast<std::size_t>(c.space)]);
    }
    double best_score = -std::numeric_limits<double>::infinity();
    std::size_t best = 0;
    for (std::size_t ci = 0; ci < candidates.size(); ++ci) {
      const Candidate& c = candidates[ci];
      if (c.used || per_space[static_cast<std::size_t>(c.space)] != least) continue;
      double score = std::numeric_limits<double>::infinity();
      for (const Eigen::Vector2d& q : chosen) score = std::min(score, (c.p - q).norm());
      if (chosen.empty()) score = -(c.p - centre).norm();  // first: nearest the middle of the floor
      if (score > best_score + 1e-9) {
        best_score = score;
        best = ci;
      }
    }
    candidates[best].used = true;
    ++per_space[static_cast<std::size_t>(candidates[best].space)];
    chosen.push_back(candidates[best].p);
  }
  std::vector<Eigen::Vector3d> beacons;
  for (const Eigen::Vector2d& p : chosen) beacons.emplace_back(p.x(), p.y(), plan.ceiling_m - params.mount_below_ceiling_m);
  return beacons;
}

OfficeUltrasonicStream::OfficeUltrasonicStream(const OfficeScenarioParams& p, const OfficeSetup& setup)
    : up_(p.ultrasonic),
      duration_s_(p.duration_s),
      t0_ns_(p.t0_ns),
      uwb_anchors_(setup.p_w_anchors.size()),
      body_azimuth_rad_(p.channel.body_shadow_azimuth_rad),
      body_max_elevation_rad_(p.channel.body_shadow_max_elevation_rad),
      setup_(setup),
      rng_(streamSeed(p.seed, kUltrasonicStream)) {
  validate(p);
  if (!setup_.walk || !setup_.plan) throw std::invalid_argument("OfficeUltrasonicStream: incomplete setup");
  beacons_ = setup_.p_w_ultrasonic.empty() ? ultrasonicBeaconsOf(*setup_.plan, p) : setup_.p_w_ultrasonic;
  SimRng field_rng(streamSeed(p.seed, kUltrasonicFieldStream));
  for (std::size_t j = 0; j < beacons_.size(); ++j) reflection_field_.emplace_back(field_rng, up_.field_length_m);
  last_t_ns_ = std::numeric_limits<std::int64_t>::min();
  stats_.duration_s = duration_s_;
  stats_.measurements_per_beacon.assign(beacons_.size(), 0);
}

double OfficeUltrasonicStream::progress() const {
  if (done_) return 1.0;
  return std::clamp(t_s_ / duration_s_, 0.0, 1.0);
}

bool OfficeUltrasonicStream::bodyBlocks(const KinematicState& body, const Eigen::Vector3d& p_w_beacon) const {
  const Eigen::Vector3d p_receiver = body.T_w_b.transformFrom(up_.p_b_receiver);
  const Eigen::Vector3d d_b = body.T_w_b.R.transpose() * (p_w_beacon - p_receiver);
  const double azimuth = std::atan2(d_b.y(), d_b.x());
  const double elevation = std::atan2(d_b.z(), d_b.head<2>().norm());
  return std::abs(azimuth) > body_azimuth_rad_ && elevation < body_max_elevation_rad_;
}

bool OfficeUltrasonicStream::next(UltrasonicSample& sample, UltrasonicTruth& truth) {
  const std::size_t beacons = beacons_.size();
  const double slot_s = 1.0 / (up_.ping_rate_hz * static_cast<double>(beacons));
  const double scale = 1.0 + up_.speed_of_sound_scale_error;
  const double c_true = up_.speed_of_sound_m_s / scale;
  const OfficePlan& plan = *setup_.plan;
  while (!done_) {
    const double t_e = static_cast<double>(slot_) * slot_s;
    if (t_e > duration_s_) {
      done_ = true;
      break;
    }
    t_s_ = t_e;
    const std::size_t j = slot_ % beacons;
    ++slot_;
    if (j == 0) ++stats_.rounds;
    ++stats_.pings;
    // The same draws every ping, so one ping's outcome does not shift the next ping's.
    const double u_dropout = rng_.uniform();
    const double u_reflection = rng_.uniform();
    const double noise = rng_.normal();

    const Eigen::Vector3d& p_beacon = beacons_[j];
    KinematicState body;
    Eigen::Vector3d p_receiver;
    double d = 0.0, t_r = t_e;
    auto receiverAt = [&](double t) {
      body = setup_.walk->at(t);
      p_receiver = body.T_w_b.transformFrom(up_.p_b_receiver);
      d = (p_receiver - p_beacon).norm();
    };
    // Arrival of the direct path: t_r = t_e + |p(t_r) - B| / c (a contraction: walking speed << c).
    receiverAt(t_e);
    for (int it = 0; it < 3; ++it) {
      t_r = t_e + d / c_true;
      receiverAt(t_r);
    }
    if (d > up_.max_range_m) {
      ++stats_.out_of_range;
      continue;
    }
    Obstruction o = obstruction(plan, p_receiver, p_beacon);
    if (o.walls() > 0) {
      ++stats_.wall_blocked;
      continue;
    }
    bool body_blocked = up_.body_blocking && bodyBlocks(body, p_beacon);
    double excess = 0.0;
    const bool reflected = !o.lineOfSight() || body_blocked;
    if (reflected) {
      if (u_reflection >= up_.reflection_probability) {
        ++stats_.obstacle_dropped;
        continue;
      }
      // Exp(1) quantile of the beacon's smooth field at the receiver: the same reflector while the geometry holds.
      const double u = std::min(normalCdf(reflection_field_[j](p_receiver)), 0.9999);
      excess = std::min(up_.reflection_max_m, up_.reflection_min_m - up_.reflection_scale_m * std::log1p(-u));
      for (int it = 0; it < 2; ++it) {
        t_r = t_e + (d + excess) / c_true;
        receiverAt(t_r);
      }
      // The sample refers to the receiver at t_r: re-check the wall and range limits there.
      o = obstruction(plan, p_receiver, p_beacon);
      body_blocked = up_.body_blocking && bodyBlocks(body, p_beacon);
      if (o.walls() > 0) {
        ++stats_.wall_blocked;
        continue;
      }
    }
    const double range = std::max(0.0, (d + excess) * scale + up_.sigma_m * noise);
    if (d > up_.max_range_m || range > up_.max_range_m) {
      ++stats_.out_of_range;
      continue;
    }
    if (u_dropout < up_.dropout) {
      ++stats_.dropouts;
      continue;
    }

    sample = UltrasonicSample{};
    sample.t_ns = std::max(t0_ns_ + toNs(t_r), last_t_ns_);  // the schedule keeps arrivals in order; guard rounding
    last_t_ns_ = sample.t_ns;
    sample.anchor_id = ultrasonicAnchorId(uwb_anchors_, j);
    sample.range_m = range;
    sample.los = reflected ? 0 : 1;

    truth = UltrasonicTruth{};
    truth.beacon = j;
    truth.true_range_m = d;
    truth.excess_m = excess;
    truth.error_m = range - d;
    truth.emit_time_s = t_e;
    truth.obstruction = o;
    truth.body_blocked = body_blocked;

    ++stats_.measurements;
    ++stats_.measurements_per_beacon[j];
    if (reflected) {
      ++stats_.reflections;
      stats_.reflection_excess_sum_m += excess;
      stats_.reflection_excess_max_m = std::max(stats_.reflection_excess_max_m, excess);
    }
    return true;
  }
  return false;
}

}  // namespace rilo::sim
