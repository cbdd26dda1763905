#include "sim/walk.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>

#include <Eigen/Geometry>

#include "sim/office_random.h"
#include "sim/walk_islands.h"

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;
constexpr double kPi = std::numbers::pi;

double cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }
double wrapPi(double a) { return std::remainder(a, 2.0 * kPi); }
Vec2 left(const Vec2& d) { return Vec2(-d.y(), d.x()); }
double smootherstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return x * x * x * (10.0 + x * (-15.0 + 6.0 * x));
}

void require(bool ok, const char* param, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("WalkParams.") + param + " " + what);
}

void validate(const WalkParams& p) {
  require(p.duration_s > 0.0 && p.duration_s <= 1e6, "duration_s", "must be in (0, 1e6] s");
  require(p.speed_min_m_s > 0.05 && p.speed_min_m_s <= p.speed_max_m_s, "speed_min_m_s", "must be in (0.05, speed_max]");
  require(p.speed_max_m_s <= 3.0, "speed_max_m_s", "must be at most 3 m/s");
  require(p.accel_m_s2 > 0.05 && p.accel_m_s2 <= 5.0, "accel_m_s2", "must be in (0.05, 5]");
  require(p.lateral_accel_m_s2 > 0.05 && p.lateral_accel_m_s2 <= 5.0, "lateral_accel_m_s2", "must be in (0.05, 5]");
  require(p.turn_radius_m > 0.05 && p.turn_radius_m <= 3.0, "turn_radius_m", "must be in (0.05, 3]");
  require(p.pause_probability >= 0.0 && p.pause_probability <= 1.0, "pause_probability", "must be in [0, 1]");
  require(p.pause_min_s >= 0.0 && p.pause_min_s <= p.pause_max_s, "pause_min_s", "must be in [0, pause_max_s]");
  require(p.same_space_probability >= 0.0 && p.same_space_probability <= 1.0, "same_space_probability",
          "must be in [0, 1]");
  require(p.initial_still_s >= 0.0, "initial_still_s", "must be >= 0");
  require(p.body_height_m >= 0.3 && p.body_height_m <= 2.0, "body_height_m", "must be in [0.3, 2] m");
  require(p.step_frequency_hz > 0.0 && p.step_frequency_hz <= 4.0, "step_frequency_hz", "must be in (0, 4] Hz");
  require(p.reference_speed_m_s > 0.0, "reference_speed_m_s", "must be > 0");
  require(p.bob_amplitude_m >= 0.0 && p.bob_amplitude_m <= 0.1, "bob_amplitude_m", "must be in [0, 0.1] m");
  require(p.sway_amplitude_m >= 0.0 && p.sway_amplitude_m <= 0.1, "sway_amplitude_m", "must be in [0, 0.1] m");
  require(std::abs(p.roll_amplitude_rad) <= 0.3 && std::abs(p.pitch_amplitude_rad) <= 0.3 &&
              std::abs(p.yaw_wobble_rad) <= 0.3 && std::abs(p.lean_rad) <= 0.3,
          "roll/pitch/yaw amplitudes", "must be at most 0.3 rad");
  require(p.turn_rate_rad_s > 0.1, "turn_rate_rad_s", "must be > 0.1 rad/s");
  require(p.control_dt_s >= 0.02 && p.control_dt_s <= 0.5, "control_dt_s", "must be in [0.02, 0.5] s");
}

struct Waypoint {
  Vec2 p;
  double speed = 1.0;  ///< cruise speed of the segment that ends here
  double pause = 0.0;  ///< stop here for this long (0: walk on)
};

/// Line or circular arc of a rounded route, by arc length.
struct Primitive {
  bool arc = false;
  Vec2 p0 = Vec2::Zero(), dir = Vec2::UnitX();  // line
  Vec2 center = Vec2::Zero();                   // arc
  double radius = 0.0, angle0 = 0.0, turn = 0.0; // arc: start angle seen from the centre, signed turn
  double s0 = 0.0, length = 0.0, speed_limit = 1.0;

  Vec2 position(double s) const {
    const double u = std::clamp(s - s0, 0.0, length);
    if (!arc) return p0 + u * dir;
    const double a = angle0 + std::copysign(u / radius, turn);
    return center + radius * Vec2(std::cos(a), std::sin(a));
  }
  double heading(double s) const {
    if (!arc) return std::atan2(dir.y(), dir.x());
    const double a = angle0 + std::copysign(std::clamp(s - s0, 0.0, length) / radius, turn);
    return a + std::copysign(0.5 * kPi, turn);
  }
};

/// One motion from standing to standing along a polyline with rounded corners.
struct Run {
  std::vector<Primitive> path;
  std::vector<double> s, t, v;  ///< speed profile table: arc length, time, speed
  double duration() const { return t.back(); }
  std::size_t primitiveAt(double s_query) const {
    std::size_t i = 0;
    while (i + 1 < path.size() && s_query > path[i].s0 + path[i].length) ++i;
    return i;
  }
  /// Arc length and speed at local time tau (piecewise linear in the table).
  void sample(double tau, std::size_t& cursor, double& s_out, double& v_out) const {
    tau = std::clamp(tau, 0.0, t.back());
    while (cursor + 2 < t.size() && t[cursor + 1] <= tau) ++cursor;
    const double dt = t[cursor + 1] - t[cursor];
    const double w = dt > 0.0 ? (tau - t[cursor]) / dt : 1.0;
    s_out = s[cursor] + w * (s[cursor + 1] - s[cursor]);
    v_out = v[cursor] + w * (v[cursor + 1] - v[cursor]);
  }
};

Run makeRun(const std::vector<Vec2>& pts, const std::vector<double>& seg_speed, const WalkParams& P) {
  const std::size_t n = pts.size();
  std::vector<Vec2> dir(n - 1);
  std::vector<double> len(n - 1);
  for (std::size_t i = 0; i + 1 < n; ++i) {
    len[i] = (pts[i + 1] - pts[i]).norm();
    dir[i] = (pts[i + 1] - pts[i]) / len[i];
  }
  // Corner rounding: tangent length T = r tan(|turn|/2), at most half of either segment.
  std::vector<double> tangent(n, 0.0), radius(n, 0.0), turn(n, 0.0);
  for (std::size_t i = 1; i + 1 < n; ++i) {
    turn[i] = std::atan2(cross2(dir[i - 1], dir[i]), dir[i - 1].dot(dir[i]));
    if (std::abs(turn[i]) < 1e-4) continue;
    const double half_tan = std::tan(0.5 * std::abs(turn[i]));
    radius[i] = std::min(P.turn_radius_m, 0.5 * std::min(len[i - 1], len[i]) / half_tan);
    tangent[i] = radius[i] * half_tan;
  }
  Run run;
  double s = 0.0;
  for (std::size_t i = 0; i + 1 < n; ++i) {
    Primitive line;
    line.p0 = pts[i] + tangent[i] * dir[i];
    line.dir = dir[i];
    line.length = std::max(0.0, len[i] - tangent[i] - tangent[i + 1]);
    line.s0 = s;
    line.speed_limit = seg_speed[i];
    s += line.length;
    if (line.length > 1e-9) run.path.push_back(line);
    if (i + 2 < n && tangent[i + 1] > 0.0) {
      const std::size_t c = i + 1;
      const Vec2 q0 = pts[c] - tangent[c] * dir[i];
      Primitive arc;
      arc.arc = true;
      arc.radius = radius[c];
      arc.turn = turn[c];
      arc.center = q0 + std::copysign(radius[c], turn[c]) * left(dir[i]);
      arc.angle0 = std::atan2(q0.y() - arc.center.y(), q0.x() - arc.center.x());
      arc.length = radius[c] * std::abs(turn[c]);
      arc.s0 = s;
      arc.speed_limit = std::min({seg_speed[i], seg_speed[i + 1], std::sqrt(P.lateral_accel_m_s2 * radius[c])});
      s += arc.length;
      run.path.push_back(arc);
    }
  }
  // Speed profile on a fine grid: limits, then forward/backward acceleration passes.
  const double total = s;
  const std::size_t N = std::max<std::size_t>(2, static_cast<std::size_t>(std::ceil(total / 0.01)));
  const double ds = total / static_cast<double>(N);
  run.s.resize(N + 1);
  run.v.resize(N + 1);
  run.t.assign(N + 1, 0.0);
  std::size_t prim = 0;
  for (std::size_t i = 0; i <= N; ++i) {
    run.s[i] = ds * static_cast<double>(i);
    while (prim + 1 < run.path.size() && run.s[i] > run.path[prim].s0 + run.path[prim].length) ++prim;
    run.v[i] = run.path[prim].speed_limit;
  }
  run.v.front() = 0.0;
  run.v.back() = 0.0;
  for (std::size_t i = 0; i < N; ++i) run.v[i + 1] = std::min(run.v[i + 1], std::sqrt(run.v[i] * run.v[i] + 2.0 * P.accel_m_s2 * ds));
  for (std::size_t i = N; i > 0; --i) run.v[i - 1] = std::min(run.v[i - 1], std::sqrt(run.v[i] * run.v[i] + 2.0 * P.accel_m_s2 * ds));
  for (std::size_t i = 0; i < N; ++i) run.t[i + 1] = run.t[i] + 2.0 * ds / (run.v[i] + run.v[i + 1]);
  return run;
}

/// Spaces on the way from `from` to `to` (fewest doors), as the doors to pass.
std::vector<int> routeDoors(const OfficePlan& plan, int from, int to) {
  std::vector<int> via_door(plan.spaces.size(), -2);
  std::vector<int> queue{from};
  via_door[static_cast<std::size_t>(from)] = -1;
  for (std::size_t q = 0; q < queue.size(); ++q) {
    const int s = queue[q];
    for (int d : plan.doorsOf(s)) {
      const int o = plan.doors[static_cast<std::size_t>(d)].other(s);
      if (via_door[static_cast<std::size_t>(o)] != -2) continue;
      via_door[static_cast<std::size_t>(o)] = d;
      queue.push_back(o);
    }
  }
  if (via_door[static_cast<std::size_t>(to)] == -2) throw std::invalid_argument("OfficePlan: space unreachable");
  std::vector<int> doors;
  for (int s = to; s != from;) {
    const int d = via_door[static_cast<std::size_t>(s)];
    doors.push_back(d);
    s = plan.doors[static_cast<std::size_t>(d)].other(s);
  }
  std::reverse(doors.begin(), doors.end());
  return doors;
}

Vec2 randomFreePoint(const Space& s, SimRng& rng) {
  return Vec2(rng.uniform(s.free_min_w.x(), s.free_max_w.x()), rng.uniform(s.free_min_w.y(), s.free_max_w.y()));
}

}  // namespace

OfficeWalk::OfficeWalk(const OfficePlan& plan, const WalkParams& params) : params_(params) {
  validate(params);
  if (plan.spaces.empty()) throw std::invalid_argument("OfficeWalk: the plan has no space");
  const WalkParams& P = params_;
  SimRng rng(streamSeed(P.seed, 0x3a1c));

  // 1. Route: destinations and door approach points with leg speeds and pauses.
  std::vector<Waypoint> wps;
  std::vector<int> rooms;
  for (std::size_t i = 0; i < plan.spaces.size(); ++i) {
    if (!plan.spaces[i].corridor) rooms.push_back(static_cast<int>(i));
  }
  int space = rooms.empty() ? 0 : rooms[rng.index(rooms.size())];
  // Islands keep this far from the route: the body (0.3 m) plus the most a
  // rounded corner (turns up to 120 degrees, sharper ones stop) cuts inside it.
  const double clearance_m = 0.3 + 0.5 * P.turn_radius_m;
  std::vector<WalkIslands> islands;
  for (const Space& s : plan.spaces) islands.emplace_back(plan, s, clearance_m);
  constexpr int kIslandTries = 200;
  Vec2 start = randomFreePoint(plan.spaces[static_cast<std::size_t>(space)], rng);
  for (int tries = 0; !islands[static_cast<std::size_t>(space)].clear(start, start); ++tries) {
    if (tries == kIslandTries) throw std::invalid_argument("OfficeWalk: no free starting point (islands fill it)");
    start = randomFreePoint(plan.spaces[static_cast<std::size_t>(space)], rng);
  }
  wps.push_back({start, 1.0, 0.0});
  const double lead_guess = P.start_moving ? 5.0 : 0.0;
  double planned = P.start_moving ? 0.0 : P.initial_still_s;
  bool first_leg = true;
  while (planned < P.duration_s + lead_guess + 10.0) {
    int next = space;
    // A moving start leaves the room at once, so the first run is long enough to reach cruise speed.
    const bool leave = (first_leg && P.start_moving) || !rng.bernoulli(P.same_space_probability);
    if (plan.spaces.size() > 1 && leave) {
      next = static_cast<int>(rng.index(plan.spaces.size() - 1));
      if (next >= space) ++next;
    }
    // In a single room (a hall) a moving start walks at least 4 m instead.
    const double min_leg_m = first_leg && P.start_moving && plan.spaces.size() == 1 ? 4.0 : 1.0;
    first_leg = false;
    const Space& next_space = plan.spaces[static_cast<std::size_t>(next)];
    Vec2 target = randomFreePoint(next_space, rng);
    for (int tries = 0; tries < 10 && (target - wps.back().p).norm() < min_leg_m; ++tries) {
      target = randomFreePoint(next_space, rng);
    }
    const std::vector<int> doors = routeDoors(plan, space, next);
    const WalkIslands& next_islands = islands[static_cast<std::size_t>(next)];
    std::vector<Vec2> around;  // corners of islands to pass on the last stretch
    if (!next_islands.empty()) {
      const Vec2 entry = doors.empty() ? wps.back().p : plan.approachPoint(doors.back(), next);
      std::optional<std::vector<Vec2>> way;
      for (int tries = 0; !way; ++tries) {
        if (tries == kIslandTries) throw std::invalid_argument("OfficeWalk: no destination reachable around islands");
        if (tries > 0) target = randomFreePoint(next_space, rng);
        if (next_islands.clear(target, target) && (target - entry).norm() >= min_leg_m) {
          way = next_islands.wayAround(entry, target);
        }
      }
      around = std::move(*way);
    }
    const double speed = rng.uniform(P.speed_min_m_s, P.speed_max_m_s);
    const Vec2 from = wps.back().p;
    const std::size_t first_new = wps.size();
    int at = space;
    for (int d : doors) {
      const int beyond = plan.doors[static_cast<std::size_t>(d)].other(at);
      wps.push_back({plan.approachPoint(d, at), speed, 0.0});
      wps.push_back({plan.approachPoint(d, beyond), speed, 0.0});
      at = beyond;
    }
    for (const Vec2& c : around) wps.push_back({c, speed, 0.0});
    const double pause = rng.bernoulli(P.pause_probability) ? rng.uniform(P.pause_min_s, P.pause_max_s) : 0.0;
    wps.push_back({target, speed, pause});
    // Time estimate (a lower bound: acceleration and turns only add time).
    double length = 0.0;
    Vec2 prev = from;
    for (std::size_t i = first_new; i < wps.size(); ++i) {
      length += (wps[i].p - prev).norm();
      prev = wps[i].p;
    }
    planned += length / speed + pause;
    space = next;
  }
  wps.back().pause = std::max(wps.back().pause, 5.0);  // end standing

  // Remove repeated points; a sharp turn without a pause becomes a short stop.
  std::vector<Waypoint> clean{wps.front()};
  for (std::size_t i = 1; i < wps.size(); ++i) {
    if ((wps[i].p - clean.back().p).norm() < 0.01) {
      clean.back().pause = std::max(clean.back().pause, wps[i].pause);
      continue;
    }
    clean.push_back(wps[i]);
  }
  for (std::size_t i = 1; i + 1 < clean.size(); ++i) {
    const Vec2 d0 = (clean[i].p - clean[i - 1].p).normalized(), d1 = (clean[i + 1].p - clean[i].p).normalized();
    if (clean[i].pause == 0.0 && d0.dot(d1) < std::cos(2.0 * kPi / 3.0)) clean[i].pause = 0.6;
  }
  for (const Waypoint& w : clean) route_.push_back(w.p);

  // 2. Runs from stop to stop.
  std::vector<Run> runs;
  std::vector<double> pauses;  // after each run
  std::size_t a = 0;
  while (a + 1 < clean.size()) {
    std::size_t b = a + 1;
    while (b + 1 < clean.size() && clean[b].pause == 0.0) ++b;
    std::vector<Vec2> pts;
    std::vector<double> speeds;
    for (std::size_t i = a; i <= b; ++i) {
      pts.push_back(clean[i].p);
      if (i > a) speeds.push_back(clean[i].speed);
    }
    runs.push_back(makeRun(pts, speeds, P));
    pauses.push_back(clean[b].pause);
    a = b;
  }

  // 3. Control points every control_dt_s: phases still, run, still, run, ...
  const double dt = P.control_dt_s;
  double phase_start = 0.0;
  auto headingAtStart = [](const Run& r) { return r.path.front().heading(0.0); };
  auto addStill = [&](const Vec2& p, double duration, double yaw_target) {
    const double yaw0 = yaw_.empty() ? yaw_target : yaw_.back();
    const double delta = yaw_.empty() ? 0.0 : wrapPi(yaw_target - yaw0);
    const double turn_time = std::abs(delta) > 1e-3 ? std::max(0.8, 1.875 * std::abs(delta) / P.turn_rate_rad_s) : 0.0;
    duration = std::max(duration, turn_time > 0.0 ? turn_time + 0.4 : 0.0);
    const double turn_start = phase_start + duration - turn_time - 0.2;
    const double end = phase_start + duration;
    while (static_cast<double>(pos_.size()) * dt < end) {
      const double t = static_cast<double>(pos_.size()) * dt;
      pos_.push_back(p);
      yaw_.push_back(turn_time > 0.0 ? yaw0 + delta * smootherstep((t - turn_start) / turn_time) : yaw0);
      gait_.push_back(0.0);
    }
    phase_start = end;
  };
  auto addRun = [&](const Run& r) {
    std::size_t cursor = 0;
    const double end = phase_start + r.duration();
    while (static_cast<double>(pos_.size()) * dt < end) {
      const double tau = static_cast<double>(pos_.size()) * dt - phase_start;
      double s = 0.0, v = 0.0;
      r.sample(tau, cursor, s, v);
      const Primitive& prim = r.path[r.primitiveAt(s)];
      const double raw = prim.heading(s);
      const double prev = yaw_.empty() ? raw : yaw_.back();
      pos_.push_back(prim.position(s));
      yaw_.push_back(prev + wrapPi(raw - prev));
      gait_.push_back(std::min(v / P.reference_speed_m_s, 1.3));
    }
    phase_start = end;
  };
  if (!P.start_moving) addStill(clean.front().p, P.initial_still_s, headingAtStart(runs.front()));
  for (std::size_t j = 0; j < runs.size(); ++j) {
    addRun(runs[j]);
    const Primitive& last = runs[j].path.back();
    const Vec2 p_end = last.position(last.s0 + last.length);
    const double next_heading = j + 1 < runs.size() ? headingAtStart(runs[j + 1]) : last.heading(last.s0 + last.length);
    addStill(p_end, pauses[j], next_heading);
  }
  // Four equal control points at the end: the spline ends at rest.
  for (int k = 0; k < 4; ++k) {
    pos_.push_back(pos_.back());
    yaw_.push_back(yaw_.back());
    gait_.push_back(0.0);
  }
  if (P.start_moving) {
    // Start where the first run first reaches its top speed (at most half-way).
    const Run& r = runs.front();
    const double v_top = *std::max_element(r.v.begin(), r.v.end());
    std::size_t i = 0;
    while (i + 1 < r.v.size() && r.v[i] < 0.98 * v_top) ++i;
    lead_s_ = std::min(r.t[i], 0.5 * r.duration());
  }
}

OfficeWalk::Basis OfficeWalk::basis(double tau) const {
  const double dt = params_.control_dt_s;
  const double u_max = static_cast<double>(pos_.size() - 1);
  const double u = std::clamp(tau / dt, 0.0, u_max);
  const bool held = tau / dt <= 0.0 || tau / dt >= u_max;
  const double k_f = std::min(std::floor(u), u_max - 1.0);
  const double f = u - k_f;
  const auto k = static_cast<std::ptrdiff_t>(k_f);
  const auto last = static_cast<std::ptrdiff_t>(pos_.size() - 1);
  Basis B{};
  for (int j = 0; j < 4; ++j) B.i[j] = static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(k - 1 + j, 0, last));
  const double g = 1.0 - f;
  B.b[0] = g * g * g / 6.0;
  B.b[1] = (3.0 * f * f * f - 6.0 * f * f + 4.0) / 6.0;
  B.b[2] = (-3.0 * f * f * f + 3.0 * f * f + 3.0 * f + 1.0) / 6.0;
  B.b[3] = f * f * f / 6.0;
  if (held) return B;  // derivatives zero: standing still outside the planned time
  B.db[0] = -0.5 * g * g / dt;
  B.db[1] = (1.5 * f * f - 2.0 * f) / dt;
  B.db[2] = (-1.5 * f * f + f + 0.5) / dt;
  B.db[3] = 0.5 * f * f / dt;
  const double dt2 = dt * dt;
  B.ddb[0] = g / dt2;
  B.ddb[1] = (3.0 * f - 2.0) / dt2;
  B.ddb[2] = (1.0 - 3.0 * f) / dt2;
  B.ddb[3] = f / dt2;
  return B;
}

KinematicState OfficeWalk::at(double t_s) const {
  const WalkParams& P = params_;
  const double tau = t_s + lead_s_;
  const Basis B = basis(tau);
  // Sums relative to the first control point (the basis sums to 1, its
  // derivatives to 0): equal control points give an exactly still state.
  const Vec2& p0 = pos_[B.i[0]];
  const double yaw0 = yaw_[B.i[0]], gait0 = gait_[B.i[0]];
  Spline2 c{p0, Vec2::Zero(), Vec2::Zero()};
  Spline1 psi{yaw0, 0.0, 0.0}, g{gait0, 0.0, 0.0};
  for (int j = 1; j < 4; ++j) {
    const Vec2 dp = pos_[B.i[j]] - p0;
    const double dyaw = yaw_[B.i[j]] - yaw0, dgait = gait_[B.i[j]] - gait0;
    c.v += B.b[j] * dp;
    c.d += B.db[j] * dp;
    c.dd += B.ddb[j] * dp;
    psi.v += B.b[j] * dyaw;
    psi.d += B.db[j] * dyaw;
    psi.dd += B.ddb[j] * dyaw;
    g.v += B.b[j] * dgait;
    g.d += B.db[j] * dgait;
    g.dd += B.ddb[j] * dgait;
  }
  // A g(t) sin(w tau + c0) and its time derivatives.
  const double w_step = 2.0 * kPi * P.step_frequency_hz;
  auto osc = [&](double A, double w, double c0) -> Spline1 {
    const double sn = std::sin(w * tau + c0), cs = std::cos(w * tau + c0);
    return {A * g.v * sn, A * (g.d * sn + g.v * w * cs), A * (g.dd * sn + 2.0 * g.d * w * cs - g.v * w * w * sn)};
  };
  const Spline1 sway = osc(P.sway_amplitude_m, 0.5 * w_step, 0.0);
  const Spline1 bob = osc(P.bob_amplitude_m, w_step, 0.0);
  const Spline1 roll = osc(P.roll_amplitude_rad, 0.5 * w_step, 1.0);
  const Spline1 pitch_osc = osc(P.pitch_amplitude_rad, w_step, 0.5);
  const Spline1 wobble = osc(P.yaw_wobble_rad, 0.5 * w_step, 0.3);

  // Sway along the left normal of the path heading.
  const double sp = std::sin(psi.v), cp = std::cos(psi.v);
  const Vec2 n(-sp, cp);
  const Vec2 n_d = Vec2(-cp, -sp) * psi.d;
  const Vec2 n_dd = Vec2(sp, -cp) * (psi.d * psi.d) + Vec2(-cp, -sp) * psi.dd;

  KinematicState s;
  const Vec2 p_xy = c.v + sway.v * n;
  const Vec2 v_xy = c.d + sway.d * n + sway.v * n_d;
  const Vec2 a_xy = c.dd + sway.dd * n + 2.0 * sway.d * n_d + sway.v * n_dd;
  s.v_w = Vec3(v_xy.x(), v_xy.y(), bob.d);
  s.a_w = Vec3(a_xy.x(), a_xy.y(), bob.dd);

  // ZYX Euler angles and rates (as in LissajousWalk).
  const double yaw = psi.v + wobble.v, yaw_d = psi.d + wobble.d;
  const double pitch = P.lean_rad * g.v + pitch_osc.v, pitch_d = P.lean_rad * g.d + pitch_osc.d;
  const double rl = roll.v, rl_d = roll.d;
  const Mat3 R = (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
                  Eigen::AngleAxisd(rl, Vec3::UnitX()))
                     .toRotationMatrix();
  const double sr = std::sin(rl), cr = std::cos(rl), spi = std::sin(pitch), cpi = std::cos(pitch);
  s.omega_b = Vec3(rl_d - yaw_d * spi, pitch_d * cr + yaw_d * sr * cpi, -pitch_d * sr + yaw_d * cr * cpi);
  s.T_w_b = Pose3(R, Vec3(p_xy.x(), p_xy.y(), P.body_height_m + bob.v));
  return s;
}

}  // namespace rilo::sim
