#include "import/physics_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <utility>

#include <Eigen/Cholesky>
#include <Eigen/Dense>

#include "hal/recording/truth_lookup.h"
#include "math/so3.h"

namespace rilo::importer {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  const double upper = *mid;
  const double lower = *std::max_element(v.begin(), mid);
  return 0.5 * (lower + upper);
}

std::int64_t toNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

AccelCheck checkAccel(const Recording& rec) {
  AccelCheck out;
  std::vector<double> norms;
  norms.reserve(rec.imu.size());
  for (const ImuSample& s : rec.imu) norms.push_back(s.accel_m_s2.norm());
  out.samples = norms.size();
  if (norms.empty()) return out;
  out.median_norm_m_s2 = median(std::move(norms));
  out.ratio_to_gravity = out.median_norm_m_s2 / rec.meta.gravity_m_s2;
  return out;
}

GyroCheck checkGyro(const Recording& rec, const PhysicsCheckParams& params, const TruthLookup& truth) {
  GyroCheck out;
  const auto& imu = rec.imu;
  if (imu.size() < 2 || rec.groundtruth.size() < 2) return out;
  const std::int64_t window_ns = toNs(params.gyro_window_s);
  const std::int64_t max_gap_ns = toNs(params.max_imu_gap_s);

  double sum_vg = 0.0, sum_gg = 0.0, sum_vv = 0.0;
  std::vector<std::pair<Vec3, Vec3>> used;  // (truth rotation, gyro integral)
  std::size_t a = 0;
  while (a + 1 < imu.size()) {
    // Window [t_a, t_b]: the first sample at least window_ns after t_a ends it.
    Vec3 theta_gyro = Vec3::Zero();
    bool gap = false;
    std::size_t b = a;
    while (b + 1 < imu.size() && imu[b].t_ns - imu[a].t_ns < window_ns) {
      const std::int64_t dt_ns = imu[b + 1].t_ns - imu[b].t_ns;
      if (dt_ns > max_gap_ns) gap = true;
      theta_gyro += imu[b].gyro_rad_s * (static_cast<double>(dt_ns) * 1e-9);  // zero-order hold
      ++b;
    }
    if (imu[b].t_ns - imu[a].t_ns < window_ns) break;  // last, incomplete window
    Mat3 R0, R1;
    Vec3 p0, p1;
    if (!gap && truth.at(imu[a].t_ns, R0, p0) && truth.at(imu[b].t_ns, R1, p1)) {
      const Vec3 theta_truth = so3::log(R0.transpose() * R1);
      const double angle = theta_truth.norm();
      if (angle >= params.min_window_rotation_rad && angle <= params.max_window_rotation_rad) {
        used.emplace_back(theta_truth, theta_gyro);
        sum_vg += theta_truth.dot(theta_gyro);
        sum_gg += theta_gyro.squaredNorm();
        sum_vv += theta_truth.squaredNorm();
        out.total_rotation_rad += angle;
      }
    }
    a = b;
  }
  out.windows = used.size();
  if (used.empty() || !(sum_gg > 0.0)) return out;
  out.scale = sum_vg / sum_gg;
  double sum_ee = 0.0;
  for (const auto& [v, g] : used) sum_ee += (v - out.scale * g).squaredNorm();
  out.relative_residual = std::sqrt(sum_ee / sum_vv);
  return out;
}

struct TdoaRow {
  std::size_t pair = 0;  ///< index into the pair list
  double r = 0.0;        ///< diff - predicted (m)
  Vec3 J_l;              ///< d predicted / d lever arm (body frame)
};

/// Least squares r = J_l . dl + b_pair over `rows`, pairs with at least
/// min_pair_samples rows. Returns false if not solvable.
struct FitResult {
  Vec3 dl = Vec3::Zero();
  Vec3 dl_sigma = Vec3::Zero();
  std::vector<double> bias, bias_sigma;
  std::vector<std::size_t> pair_samples;
  std::vector<int> column;  ///< pair -> unknown index (3 + k), -1 if out of the fit
  double sigma = 0.0;
  std::size_t samples = 0;
};

bool solveFit(const std::vector<TdoaRow>& rows, std::size_t pairs, std::size_t min_pair_samples, FitResult& fit) {
  std::vector<std::size_t> count(pairs, 0);
  for (const TdoaRow& row : rows) ++count[row.pair];
  fit.column.assign(pairs, -1);
  int m = 3;
  for (std::size_t k = 0; k < pairs; ++k) {
    if (count[k] >= min_pair_samples) fit.column[k] = m++;
  }
  Eigen::MatrixXd N = Eigen::MatrixXd::Zero(m, m);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(m);
  std::size_t n = 0;
  for (const TdoaRow& row : rows) {
    const int c = fit.column[row.pair];
    if (c < 0) continue;
    N.topLeftCorner<3, 3>() += row.J_l * row.J_l.transpose();
    N.block<3, 1>(0, c) += row.J_l;
    N.block<1, 3>(c, 0) += row.J_l.transpose();
    N(c, c) += 1.0;
    rhs.head<3>() += row.J_l * row.r;
    rhs(c) += row.r;
    ++n;
  }
  if (n <= static_cast<std::size_t>(m) + 3) return false;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(N);
  if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || !(ldlt.rcond() > 1e-12)) return false;
  const Eigen::VectorXd x = ldlt.solve(rhs);
  double sum_ee = 0.0;
  for (const TdoaRow& row : rows) {
    const int c = fit.column[row.pair];
    if (c < 0) continue;
    const double e = row.r - row.J_l.dot(x.head<3>()) - x(c);
    sum_ee += e * e;
  }
  fit.samples = n;
  fit.sigma = std::sqrt(sum_ee / static_cast<double>(n - static_cast<std::size_t>(m)));
  const Eigen::MatrixXd cov = fit.sigma * fit.sigma * ldlt.solve(Eigen::MatrixXd::Identity(m, m));
  fit.dl = x.head<3>();
  for (int i = 0; i < 3; ++i) fit.dl_sigma(i) = std::sqrt(std::max(cov(i, i), 0.0));
  fit.bias.assign(pairs, 0.0);
  fit.bias_sigma.assign(pairs, 0.0);
  fit.pair_samples = count;
  for (std::size_t k = 0; k < pairs; ++k) {
    const int c = fit.column[k];
    if (c < 0) continue;
    fit.bias[k] = x(c);
    fit.bias_sigma[k] = std::sqrt(std::max(cov(c, c), 0.0));
  }
  return true;
}

TdoaCheck checkTdoa(const Recording& rec, const PhysicsCheckParams& params, const TruthLookup& truth) {
  TdoaCheck out;
  if (rec.tdoa.empty() || rec.groundtruth.empty()) return out;
  std::unordered_map<std::uint32_t, Vec3> anchor_at;
  for (const Anchor& a : rec.anchors) {
    if (a.kind == AnchorKind::kUwb) anchor_at.emplace(a.id, a.p_w_anchor);
  }
  const Vec3 l = rec.meta.uwbLeverArm();

  std::map<std::pair<std::uint32_t, std::uint32_t>, std::size_t> pair_index;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pair_ids;
  std::vector<TdoaRow> rows;
  std::vector<double> abs_r, abs_r_flipped, signed_r;
  for (const TdoaSample& s : rec.tdoa) {
    const auto A_a = anchor_at.find(s.anchor_a);
    const auto A_b = anchor_at.find(s.anchor_b);
    if (A_a == anchor_at.end() || A_b == anchor_at.end()) continue;
    Mat3 R_w_b;
    Vec3 p_w_b;
    if (!truth.at(s.t_ns, R_w_b, p_w_b)) continue;
    const Vec3 p = p_w_b + R_w_b * l;
    const Vec3 to_a = p - A_a->second;
    const Vec3 to_b = p - A_b->second;
    const double d_a = to_a.norm();
    const double d_b = to_b.norm();
    if (!(d_a > 1e-6 && d_b > 1e-6)) continue;
    const double predicted = d_b - d_a;
    const double r = s.diff_m - predicted;
    abs_r.push_back(std::abs(r));
    abs_r_flipped.push_back(std::abs(-s.diff_m - predicted));
    signed_r.push_back(r);
    const auto key = std::make_pair(s.anchor_a, s.anchor_b);
    auto [it, inserted] = pair_index.emplace(key, pair_ids.size());
    if (inserted) pair_ids.push_back(key);
    TdoaRow row;
    row.pair = it->second;
    row.r = r;
    row.J_l = R_w_b.transpose() * (to_b / d_b - to_a / d_a);
    rows.push_back(row);
  }
  out.samples = abs_r.size();
  if (abs_r.empty()) return out;
  out.median_abs_residual_m = median(std::move(abs_r));
  out.median_abs_residual_flipped_m = median(std::move(abs_r_flipped));
  out.median_residual_m = median(std::move(signed_r));

  // Pass 1 on the residuals under the gate, pass 2 on those within 3 robust
  // sigmas of the pass-1 fit: NLOS outliers stay out of the figures.
  std::vector<TdoaRow> gated;
  for (const TdoaRow& row : rows) {
    if (std::abs(row.r) <= params.fit_gate_m) gated.push_back(row);
  }
  FitResult fit;
  if (!solveFit(gated, pair_ids.size(), params.min_pair_samples, fit)) return out;
  std::vector<double> abs_e;
  for (const TdoaRow& row : gated) {
    const int c = fit.column[row.pair];
    if (c >= 0) abs_e.push_back(std::abs(row.r - row.J_l.dot(fit.dl) - fit.bias[row.pair]));
  }
  const double gate2 = std::max(3.0 * 1.4826 * median(abs_e), 0.01);
  std::vector<TdoaRow> inliers;
  for (const TdoaRow& row : gated) {
    const int c = fit.column[row.pair];
    if (c >= 0 && std::abs(row.r - row.J_l.dot(fit.dl) - fit.bias[row.pair]) <= gate2) inliers.push_back(row);
  }
  FitResult fit2;
  if (!solveFit(inliers, pair_ids.size(), params.min_pair_samples, fit2)) return out;

  out.fit_ok = true;
  out.fit_samples = fit2.samples;
  out.fit_sigma_m = fit2.sigma;
  out.lever_arm_correction_m = fit2.dl;
  out.lever_arm_sigma_m = fit2.dl_sigma;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(fit2.dl(i)) > std::max(params.lever_arm_evident_m, 3.0 * fit2.dl_sigma(i))) {
      out.lever_arm_evident = true;
    }
  }
  for (std::size_t k = 0; k < pair_ids.size(); ++k) {
    if (fit2.column[k] < 0) continue;
    PairBias pb;
    pb.anchor_a = pair_ids[k].first;
    pb.anchor_b = pair_ids[k].second;
    pb.samples = fit2.pair_samples[k];
    pb.bias_m = fit2.bias[k];
    pb.sigma_m = fit2.bias_sigma[k];
    pb.evident = std::abs(pb.bias_m) > std::max(params.bias_evident_m, 3.0 * pb.sigma_m);
    out.pair_biases.push_back(pb);
  }
  std::sort(out.pair_biases.begin(), out.pair_biases.end(),
            [](const PairBias& x, const PairBias& y) { return std::abs(x.bias_m) > std::abs(y.bias_m); });
  return out;
}

}  // namespace

PhysicsCheck checkPhysics(const Recording& rec, const PhysicsCheckParams& params) {
  const TruthLookup truth(rec.groundtruth, toNs(params.max_truth_gap_s));
  PhysicsCheck out;
  out.accel = checkAccel(rec);
  out.gyro = checkGyro(rec, params, truth);
  out.tdoa = checkTdoa(rec, params, truth);
  return out;
}

}  // namespace rilo::importer
