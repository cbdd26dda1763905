#include "sim/walk_islands.h"

#include <cmath>
#include <limits>

namespace rilo::sim {
namespace {

using Vec2 = Eigen::Vector2d;

constexpr double kCornerOffsetM = 0.02;  // graph nodes this far outside the grown boxes

}  // namespace

WalkIslands::WalkIslands(const OfficePlan& plan, const Space& s, double clearance_m) {
  for (const Obstacle& o : plan.obstacles) {
    const bool inside =
        (o.min_w.array() < s.free_max_w.array()).all() && (s.free_min_w.array() < o.max_w.array()).all();
    if (!inside) continue;
    lo_.push_back(o.min_w - Vec2::Constant(clearance_m));
    hi_.push_back(o.max_w + Vec2::Constant(clearance_m));
  }
  for (std::size_t i = 0; i < lo_.size(); ++i) {
    const Vec2 lo = lo_[i] - Vec2::Constant(kCornerOffsetM), hi = hi_[i] + Vec2::Constant(kCornerOffsetM);
    for (const Vec2& c : {lo, Vec2(hi.x(), lo.y()), hi, Vec2(lo.x(), hi.y())}) {
      if (s.inFree(c) && clear(c, c)) corners_.push_back(c);
    }
  }
}

bool WalkIslands::clear(const Vec2& a, const Vec2& b) const {
  const Vec2 d = b - a;
  for (std::size_t k = 0; k < lo_.size(); ++k) {
    double t0 = 0.0, t1 = 1.0;
    bool hit = true;
    for (int i = 0; i < 2 && hit; ++i) {
      if (std::abs(d(i)) < 1e-12) {
        hit = a(i) >= lo_[k](i) && a(i) <= hi_[k](i);
        continue;
      }
      const double ta = (lo_[k](i) - a(i)) / d(i), tb = (hi_[k](i) - a(i)) / d(i);
      t0 = std::max(t0, std::min(ta, tb));
      t1 = std::min(t1, std::max(ta, tb));
      hit = t0 <= t1;
    }
    if (hit) return false;
  }
  return true;
}

std::optional<std::vector<Vec2>> WalkIslands::wayAround(const Vec2& a, const Vec2& b) const {
  if (clear(a, b)) return std::vector<Vec2>{};
  // Dijkstra over a, the corners, b (dense: a few dozen nodes).
  std::vector<Vec2> nodes{a};
  nodes.insert(nodes.end(), corners_.begin(), corners_.end());
  nodes.push_back(b);
  const std::size_t n = nodes.size(), goal = n - 1;
  std::vector<double> dist{0.0};  // from a
  dist.resize(n, std::numeric_limits<double>::infinity());
  std::vector<std::size_t> prev(n, n);
  std::vector<bool> done(n, false);
  for (;;) {
    std::size_t u = n;
    for (std::size_t i = 0; i < n; ++i) {
      if (!done[i] && std::isfinite(dist[i]) && (u == n || dist[i] < dist[u])) u = i;
    }
    if (u == n) return std::nullopt;
    if (u == goal) break;
    done[u] = true;
    for (std::size_t v = 0; v < n; ++v) {
      if (done[v] || v == u) continue;
      const double d = dist[u] + (nodes[v] - nodes[u]).norm();
      if (d < dist[v] && clear(nodes[u], nodes[v])) {
        dist[v] = d;
        prev[v] = u;
      }
    }
  }
  std::vector<Vec2> via;
  for (std::size_t v = prev[goal]; v != 0; v = prev[v]) via.push_back(nodes[v]);
  return std::vector<Vec2>(via.rbegin(), via.rend());
}

}  // namespace rilo::sim
