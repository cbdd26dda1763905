// Where locateTdoa's hypotheses come from: the pair graph (the rows' pair
// medians solved for one pseudo-range per anchor), ultrasonic trilateration,
// the anchors' best-fit plane (for mirror starts) and the 4-anchor subsets of
// the consensus. The TDoA closed form itself is tdoa_closed_form.cpp.
#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <utility>

#include "estimation/init/tdoa_detail.h"

namespace rilo::tdoa_detail {

PairGraph buildPairGraph(const std::vector<Row>& rows) {
  PairGraph out;
  std::map<std::uint32_t, int> index;
  for (const Row& o : rows) {
    index.emplace(o.id_a, 0);
    index.emplace(o.id_b, 0);
  }
  std::vector<std::uint32_t> ids;
  for (auto& [id, k] : index) {
    k = static_cast<int>(ids.size());
    ids.push_back(id);
  }
  const int n = static_cast<int>(ids.size());
  out.anchors_total = n;
  if (n == 0) return out;

  // Per unordered pair (lo < hi): values of D_hi - D_lo.
  std::map<std::pair<int, int>, std::vector<double>> pairs;
  std::vector<int> rows_of(static_cast<std::size_t>(n), 0);
  std::vector<int> parent(static_cast<std::size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  auto find = [&](int k) {
    while (parent[static_cast<std::size_t>(k)] != k) {
      parent[static_cast<std::size_t>(k)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(k)])];
      k = parent[static_cast<std::size_t>(k)];
    }
    return k;
  };
  for (const Row& o : rows) {
    const int ka = index.at(o.id_a), kb = index.at(o.id_b);
    if (ka < kb) {
      pairs[{ka, kb}].push_back(o.diff_m);
    } else {
      pairs[{kb, ka}].push_back(-o.diff_m);
    }
    ++rows_of[static_cast<std::size_t>(ka)];
    ++rows_of[static_cast<std::size_t>(kb)];
    parent[static_cast<std::size_t>(find(ka))] = find(kb);
  }
  // Largest component (anchors, then rows).
  std::map<int, std::pair<int, int>> comp;  // root -> (anchors, rows)
  for (int k = 0; k < n; ++k) {
    auto& c = comp[find(k)];
    ++c.first;
    c.second += rows_of[static_cast<std::size_t>(k)];
  }
  out.components = static_cast<int>(comp.size());
  int best_root = comp.begin()->first;
  for (const auto& [root, c] : comp) {
    if (c > comp[best_root]) best_root = root;
  }
  std::vector<int> members;
  for (int k = 0; k < n; ++k) {
    if (find(k) == best_root) members.push_back(k);
  }
  // Reference: the member with most rows.
  std::stable_sort(members.begin(), members.end(), [&](int x, int y) {
    return rows_of[static_cast<std::size_t>(x)] > rows_of[static_cast<std::size_t>(y)];
  });
  const int m = static_cast<int>(members.size());
  std::vector<int> local(static_cast<std::size_t>(n), -1);
  for (int i = 0; i < m; ++i) local[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])] = i;

  // Weighted least squares over the pair medians, D_root = 0 (Laplacian
  // system), weights = 1 / variance of the median in row variances (the mean
  // of 1-2 rows; pi / (2 n) for n >= 3).
  Eigen::MatrixXd L = Eigen::MatrixXd::Zero(m, m);
  VecX rhs = VecX::Zero(m);
  for (auto& [pair, values] : pairs) {
    const int i = local[static_cast<std::size_t>(pair.first)], j = local[static_cast<std::size_t>(pair.second)];
    if (i < 0 || j < 0) continue;
    const auto n_rows = static_cast<double>(values.size());
    const double w = values.size() <= 2 ? n_rows : 2.0 * n_rows / M_PI;
    const double v = median(values);
    L(i, i) += w;
    L(j, j) += w;
    L(i, j) -= w;
    L(j, i) -= w;
    rhs(j) += w * v;
    rhs(i) -= w * v;
  }
  VecX D = VecX::Zero(m);
  if (m > 1) D.tail(m - 1) = L.bottomRightCorner(m - 1, m - 1).ldlt().solve(rhs.tail(m - 1));
  // Covariance of D up to the common offset: the pseudo-inverse of L (its
  // gauge is the one of least variance, sum D = 0).
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(L);
  VecX var = VecX::Zero(m);
  const double lambda_max = eig.eigenvalues().maxCoeff();
  for (int k = 0; k < m; ++k) {
    const double lambda = eig.eigenvalues()(k);
    if (lambda > 1e-9 * lambda_max) var += eig.eigenvectors().col(k).cwiseAbs2() / lambda;
  }
  for (int i = 0; i < m; ++i) {
    out.anchors.push_back(ids[static_cast<std::size_t>(members[static_cast<std::size_t>(i)])]);
    out.D.push_back(D(i));
    out.sd.push_back(std::sqrt(std::max(var(i), 1e-6)));
  }
  return out;
}

/// Ultrasonic trilateration (IMU-Ultrasonic-UWB paper, eq. 8, sphere
/// subtraction): 2 V_j^T x = rho_0^2 + |V_j|^2 - rho_j^2 with x = p - U_0.
/// Coplanar beacons (the ceiling): in-plane part by least squares,
/// out-of-plane +-t.
int rangeIntersection(const std::vector<Vec3>& beacons, const std::vector<double>& ranges, std::array<Vec3, 2>& out) {
  const auto n = static_cast<Eigen::Index>(beacons.size());
  if (n < 3) return 0;
  MatX3 V(n - 1, 3);
  VecX c(n - 1);
  for (Eigen::Index j = 1; j < n; ++j) {
    const Vec3 v = beacons[static_cast<std::size_t>(j)] - beacons[0];
    V.row(j - 1) = 2.0 * v.transpose();
    c(j - 1) = ranges[0] * ranges[0] + v.squaredNorm() -
               ranges[static_cast<std::size_t>(j)] * ranges[static_cast<std::size_t>(j)];
  }
  const Eigen::JacobiSVD<MatX3> svd(V, Eigen::ComputeFullV);
  const Vec3 sv = svd.singularValues();
  if (!(sv(0) > 1e-9) || sv(1) <= 1e-6 * sv(0)) return 0;
  if (sv(2) > 1e-2 * sv(0)) {
    out[0] = beacons[0] + Vec3(V.colPivHouseholderQr().solve(c));
    return out[0].allFinite() ? 1 : 0;
  }
  const Eigen::Matrix<double, 3, 2> E = svd.matrixV().leftCols<2>();
  const Vec3 normal = svd.matrixV().col(2);
  const Eigen::Vector2d u = (V * E).colPivHouseholderQr().solve(c);
  const Vec3 x_plane = E * u;
  double t2 = 0.0;
  for (Eigen::Index j = 0; j < n; ++j) {
    const Vec3 v = beacons[static_cast<std::size_t>(j)] - beacons[0];
    const double rj = ranges[static_cast<std::size_t>(j)];
    t2 += rj * rj - (x_plane - v).squaredNorm();
  }
  const double t = std::sqrt(std::max(0.0, t2 / static_cast<double>(n)));
  out[0] = beacons[0] + x_plane + t * normal;
  out[1] = beacons[0] + x_plane - t * normal;
  return out[0].allFinite() ? 2 : 0;
}

/// Best-fit plane (centroid, unit normal with n.z >= 0) of points; false for < 3.
bool bestFitPlane(const std::vector<Vec3>& pts, Vec3& centroid, Vec3& normal) {
  if (pts.size() < 3) return false;
  centroid = Vec3::Zero();
  for (const Vec3& p : pts) centroid += p;
  centroid /= static_cast<double>(pts.size());
  MatX3 centered(static_cast<Eigen::Index>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i)
    centered.row(static_cast<Eigen::Index>(i)) = (pts[i] - centroid).transpose();
  const Eigen::JacobiSVD<MatX3> svd(centered, Eigen::ComputeFullV);
  normal = svd.matrixV().col(2);
  if (normal.z() < 0.0) normal = -normal;
  return true;
}

double binomial(int n, int k) {
  double c = 1.0;
  for (int i = 1; i <= k; ++i) c = c * static_cast<double>(n - k + i) / static_cast<double>(i);
  return c;
}

/// 4-anchor subsets of {0..m-1}: all of them (lexicographic) up to `max`,
/// else `max` random ones from a fixed seed (deterministic fixes).
std::vector<std::array<int, 4>> anchorSubsets(int m, int max) {
  std::vector<std::array<int, 4>> out;
  if (m < 5) return out;  // with 4 anchors the all-anchor closed form is the only subset
  if (binomial(m, 4) <= static_cast<double>(max)) {
    for (int a = 0; a < m; ++a)
      for (int b = a + 1; b < m; ++b)
        for (int c = b + 1; c < m; ++c)
          for (int d = c + 1; d < m; ++d) out.push_back({a, b, c, d});
    return out;
  }
  std::mt19937 rng(0x7d0a5eedU);
  std::vector<int> idx(static_cast<std::size_t>(m));
  std::iota(idx.begin(), idx.end(), 0);
  std::set<std::array<int, 4>> seen;
  for (int tries = 0; static_cast<int>(out.size()) < max && tries < 20 * max; ++tries) {
    for (int i = 0; i < 4; ++i) {
      std::uniform_int_distribution<int> pick(i, m - 1);
      std::swap(idx[static_cast<std::size_t>(i)], idx[static_cast<std::size_t>(pick(rng))]);
    }
    std::array<int, 4> s{idx[0], idx[1], idx[2], idx[3]};
    std::sort(s.begin(), s.end());
    if (seen.insert(s).second) out.push_back(s);
  }
  return out;
}

}  // namespace rilo::tdoa_detail
