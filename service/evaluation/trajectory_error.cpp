#include "evaluation/trajectory_error.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace rilo {

ErrorStats errorStats(std::vector<double> e) {
  ErrorStats s;
  s.count = e.size();
  if (e.empty()) return s;
  double sum = 0.0, sum2 = 0.0;
  for (double v : e) {
    sum += v;
    sum2 += v * v;
    s.max = std::max(s.max, v);
  }
  const auto n = static_cast<double>(e.size());
  s.mean = sum / n;
  s.rmse = std::sqrt(sum2 / n);
  const std::size_t mid = e.size() / 2;
  std::nth_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(mid), e.end());
  s.median = e[mid];
  if (e.size() % 2 == 0) {
    s.median = 0.5 * (s.median + *std::max_element(e.begin(), e.begin() + static_cast<std::ptrdiff_t>(mid)));
  }
  return s;
}

PositionErrorStats positionErrorStats(const std::vector<Vec3>& p_est, const std::vector<Vec3>& p_true) {
  if (p_est.size() != p_true.size()) throw std::invalid_argument("positionErrorStats: size mismatch");
  std::vector<double> e3, eh, ev;
  double sum_dz = 0.0;
  e3.reserve(p_est.size());
  eh.reserve(p_est.size());
  ev.reserve(p_est.size());
  for (std::size_t i = 0; i < p_est.size(); ++i) {
    const Vec3 d = p_est[i] - p_true[i];
    e3.push_back(d.norm());
    eh.push_back(d.head<2>().norm());
    ev.push_back(std::abs(d.z()));
    sum_dz += d.z();
  }
  const double bias = p_est.empty() ? 0.0 : sum_dz / static_cast<double>(p_est.size());
  return {errorStats(std::move(e3)), errorStats(std::move(eh)), errorStats(std::move(ev)), bias};
}

}  // namespace rilo
