#include "estimation/init/alignment.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "estimation/init/range_loss.h"
#include "estimation/noise/noise_model_factory.h"

namespace rilo {

void AlignmentParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("AlignmentParams.") + field + " " + rule);
  };
  if (!(range_sigma_m > 0.0) || !std::isfinite(range_sigma_m)) fail("range_sigma_m", "must be finite and > 0");
  if (!(tdoa_sigma_m > 0.0) || !std::isfinite(tdoa_sigma_m)) fail("tdoa_sigma_m", "must be finite and > 0");
  if (!(ultrasonic_sigma_m > 0.0) || !std::isfinite(ultrasonic_sigma_m)) fail("ultrasonic_sigma_m", "must be finite and > 0");
  if (!p_b_ultrasonic.allFinite()) fail("p_b_ultrasonic", "must be finite");
  for (const Vec3& b : p_w_ultrasonic) {
    if (!b.allFinite()) fail("p_w_ultrasonic", "must be finite");
  }
  if (!(short_side_huber_k > 0.0)) fail("short_side_huber_k", "must be > 0");
  if (!p_b_tag.allFinite()) fail("p_b_tag", "must be finite");
  validateTagLeverArms(tag_lever_arms, "AlignmentParams.");
  if (!(gravity_m_s2 > 0.0) || !std::isfinite(gravity_m_s2)) fail("gravity_m_s2", "must be finite and > 0");
  if (!(accel_bias_sigma > 0.0)) fail("accel_bias_sigma", "must be > 0");
  if (!(gyro_bias_sigma > 0.0)) fail("gyro_bias_sigma", "must be > 0");
  if (!(vertical_velocity_sigma_m_s > 0.0)) fail("vertical_velocity_sigma_m_s", "must be > 0 (+inf disables)");
  if (yaw_hypotheses < 1) fail("yaw_hypotheses", "must be >= 1");
  if (max_iterations < 1) fail("max_iterations", "must be >= 1");
  if (!(distinct_yaw_rad > 0.0)) fail("distinct_yaw_rad", "must be > 0");
  band.validate("AlignmentParams.band");
}

namespace {

using Vec15d = Eigen::Matrix<double, 15, 1>;
using Mat15d = Eigen::Matrix<double, 15, 15>;

// Unknowns, in this order: rotation (right perturbation of R_r), p_r, v_r, b_a, b_g.
constexpr int kRot = 0, kPos = 3, kVel = 6, kBa = 9, kBg = 12;

struct Obs {
  Measurement::Kind kind;
  Vec3 a, b;                  ///< anchor (beacon); TDoA: anchors a and b
  double value_m;
  double inv_sigma;
  const Vec3* p_b_sensor;     ///< lever arm of the antenna or receiver
  const StrapdownDelta* delta;

  /// Predicted value at the sensor position and its gradient there.
  double predict(const Vec3& p_sensor, Eigen::RowVector3d* grad) const {
    const Vec3 da = p_sensor - a;
    const double na = std::max(da.norm(), 1e-9);
    if (kind != Measurement::Kind::kTdoa) {
      if (grad) *grad = (da / na).transpose();
      return na;
    }
    const Vec3 db = p_sensor - b;
    const double nb = std::max(db.norm(), 1e-9);
    if (grad) *grad = (db / nb - da / na).transpose();
    return nb - na;
  }
};

struct State {
  Mat3 R = Mat3::Identity();
  Vec3 p = Vec3::Zero(), v = Vec3::Zero();
  ImuBias b;
};

struct Problem {
  std::vector<Obs> obs;
  InitRangeLoss loss;
  const AlignmentParams* params;
  const GravityAlignment* gravity;
  Vec3 g_w;
};

/// Robust loss of one whitened residual (see the header).
double rhoOf(const Problem& pr, const Obs& o, double r) {
  return o.kind == Measurement::Kind::kTdoa ? pr.loss.long_side->loss(std::abs(r)) : pr.loss.rho(r);
}
double weightOf(const Problem& pr, const Obs& o, double r) {
  return o.kind == Measurement::Kind::kTdoa ? pr.loss.long_side->weight(std::abs(r)) : pr.loss.weight(r);
}

/// The gyro-bias correction Exp(phi) of one delta's rotation, applied to
/// vectors without forming the matrix: R = I + a W + b W^2 with W = hat(phi)
/// (so3::exp's coefficients), so v -> v + a phi x v + b phi x (phi x v). The
/// alignment evaluates it at every measurement for every cost and
/// linearization; two cross products instead of a matrix exponential and a
/// 3x3 product.
struct SmallRotation {
  Vec3 phi;
  double a, b;
  explicit SmallRotation(const Vec3& phi_rad) : phi(phi_rad) {
    const double theta2 = phi.squaredNorm();
    if (theta2 < 2.5e-3) {
      // theta < 0.05 rad (a gyro-bias correction always is): the series of
      // sin(theta) / theta and (1 - cos theta) / theta^2 to theta^8, exact to
      // double precision there (next terms < 3e-21), without sin and cos.
      const double t2 = theta2, t4 = t2 * t2;
      a = 1.0 - t2 / 6.0 + t4 / 120.0 - t4 * t2 / 5040.0 + t4 * t4 / 362880.0;
      b = 0.5 - t2 / 24.0 + t4 / 720.0 - t4 * t2 / 40320.0 + t4 * t4 / 3628800.0;
    } else if (theta2 < 0.25) {
      // theta < 0.5 rad (the gyro-bias prior's sigma over a window of tens of
      // seconds): the same series to theta^16, in Horner form; the next terms
      // are < 4e-23, so this is sin and cos to rounding, at a fraction of the
      // two library calls (they were ~5 % of a replay's CPU).
      const double t = theta2;
      a = 1.0 + t * (-1.0 / 6.0 + t * (1.0 / 120.0 + t * (-1.0 / 5040.0 + t * (1.0 / 362880.0 + t * (-1.0 / 39916800.0 +
          t * (1.0 / 6227020800.0 + t * (-1.0 / 1307674368000.0 + t * (1.0 / 355687428096000.0))))))));
      b = 0.5 + t * (-1.0 / 24.0 + t * (1.0 / 720.0 + t * (-1.0 / 40320.0 + t * (1.0 / 3628800.0 + t * (-1.0 / 479001600.0 +
          t * (1.0 / 87178291200.0 + t * (-1.0 / 20922789888000.0 + t * (1.0 / 6402373705728000.0))))))));
    } else {
      const double theta = std::sqrt(theta2);
      const double s_half = std::sin(0.5 * theta);
      a = std::sin(theta) / theta;
      b = 2.0 * s_half * s_half / theta2;
    }
  }
  Vec3 rotate(const Vec3& v) const {
    const Vec3 c = phi.cross(v);
    return v + a * c + b * phi.cross(c);
  }
  Vec3 inverseRotate(const Vec3& v) const {  // Exp(phi)^T v = Exp(-phi) v
    const Vec3 c = phi.cross(v);
    return v - a * c + b * phi.cross(c);
  }
};

/// The sensor (antenna or receiver) position at one measurement time, with
/// what its Jacobian needs.
struct TagEval {
  Vec3 tag;
  Vec3 x_b;  ///< R_r^T (tag - p_r - v_r dt - g dt^2 / 2): corrected dp plus the rotated lever arm
  SmallRotation corr;
};

TagEval tagAt(const Problem& pr, const State& s, const Obs& o) {
  const StrapdownDelta& d = *o.delta;
  // StrapdownDelta::corrected(s.b), only the parts the track needs.
  TagEval e{Vec3::Zero(), Vec3::Zero(), SmallRotation(d.dR_dbg * s.b.gyro)};
  const Vec3 dp = d.dp + d.dp_dba * s.b.accel + d.dp_dbg * s.b.gyro;
  const Vec3 lever = d.dR * e.corr.rotate(*o.p_b_sensor);
  e.x_b = dp + lever;
  e.tag = s.p + s.v * d.dt_s + 0.5 * pr.g_w * d.dt_s * d.dt_s + s.R * e.x_b;
  return e;
}

/// g^T J for a world-frame row g, J the 3 x 15 Jacobian of the sensor
/// position (tagAt) w.r.t. [rot, p_r, v_r, b_a, b_g]:
///   J = [-R hat(x_b), I, dt I, R dp_dba, R (dp_dbg - dR(b) hat(p_b) dR_dbg)]
/// evaluated as vector products (u = R^T g).
Eigen::Matrix<double, 1, 15> rowJacobian(const State& s, const Obs& o, const TagEval& e, const Vec3& g) {
  const StrapdownDelta& d = *o.delta;
  const Vec3 u = s.R.transpose() * g;
  const Vec3 w = e.corr.inverseRotate(d.dR.transpose() * u);  // dR(b)^T u
  Eigen::Matrix<double, 1, 15> Jg;
  Jg.segment<3>(kRot) = e.x_b.cross(u).transpose();
  Jg.segment<3>(kPos) = g.transpose();
  Jg.segment<3>(kVel) = d.dt_s * g.transpose();
  Jg.segment<3>(kBa) = (d.dp_dba.transpose() * u).transpose();
  Jg.segment<3>(kBg) = (d.dp_dbg.transpose() * u - d.dR_dbg.transpose() * w.cross(*o.p_b_sensor)).transpose();
  return Jg;
}

struct Costs {
  double total = 0.0;
  double measurements = 0.0;
};

/// One measurement evaluated at a state: what the cost needs and what the
/// linearization at the same state reuses (the cost of an accepted step is
/// evaluated at the state the next iteration linearizes at).
struct ObsEval {
  TagEval e;
  Eigen::RowVector3d grad;  ///< of the predicted value w.r.t. the sensor position
  double r;                 ///< whitened residual
};
using ObsEvals = std::vector<ObsEval>;

/// The height band's residual applies to the UWB antenna only.
bool onBand(const Obs& o) { return o.kind != Measurement::Kind::kUltrasonic; }

/// The cost at s; every measurement's evaluation into *evals (resized).
/// Every term is >= 0 (robust_loss.h: rho(0) = 0, non-decreasing in |r|), so
/// once the partial sum passes `reject_above` the total will too (rounding is
/// monotone): a step's rejection is then certain, and the rest of the sum
/// is skipped (+inf returned, *evals incomplete).
Costs costOf(const Problem& pr, const State& s, ObsEvals* evals,
             double reject_above = std::numeric_limits<double>::infinity()) {
  const AlignmentParams& P = *pr.params;
  Costs c;
  constexpr std::size_t kCheckEvery = 64;
  evals->resize(pr.obs.size(), ObsEval{TagEval{Vec3::Zero(), Vec3::Zero(), SmallRotation(Vec3::Zero())},
                                       Eigen::RowVector3d::Zero(), 0.0});
  for (std::size_t j = 0; j < pr.obs.size(); ++j) {
    const Obs& o = pr.obs[j];
    ObsEval& ev = (*evals)[j];
    ev.e = tagAt(pr, s, o);
    const Vec3& tag = ev.e.tag;
    ev.r = (o.value_m - o.predict(tag, &ev.grad)) * o.inv_sigma;
    c.measurements += rhoOf(pr, o, ev.r);
    if (onBand(o)) {
      const double rb = P.band.residual(tag.z());
      c.total += 0.5 * rb * rb;
    }
    if ((j + 1) % kCheckEvery == 0 && c.total + c.measurements > reject_above) {
      const double inf = std::numeric_limits<double>::infinity();
      return Costs{inf, inf};
    }
  }
  c.total += c.measurements;
  c.total += 0.5 * (s.b.accel / P.accel_bias_sigma).squaredNorm();
  c.total += 0.5 * (s.b.gyro / P.gyro_bias_sigma).squaredNorm();
  c.total += 0.5 * ((s.R.transpose() * Vec3::UnitZ() - pr.gravity->up_b) / pr.gravity->tilt_sigma_rad).squaredNorm();
  if (std::isfinite(P.vertical_velocity_sigma_m_s)) {
    const double rz = s.v.z() / P.vertical_velocity_sigma_m_s;
    c.total += 0.5 * rz * rz;
  }
  return c;
}

/// H += w J^T J on the lower triangle only (linearize mirrors it once at the
/// end; the LDLT and the eigensolver read the lower triangle): Eigen's outer
/// product there, H(r, c) += (w J(r)) J(c), bit for bit, at half the work.
inline void addOuterLower(Mat15d& H, const Eigen::Matrix<double, 1, 15>& J, double w) {
  double wJ[15];
  for (int r = 0; r < 15; ++r) wJ[r] = w * J(r);
  double* h = H.data();  // column-major: column c starts at h + 15 c
  for (int c = 0; c < 15; ++c) {
    const double jc = J(c);
    for (int r = c; r < 15; ++r) h[15 * c + r] += wJ[r] * jc;
  }
}

/// Normal equations at s, from the measurements' evaluations there (costOf's).
void linearize(const Problem& pr, const State& s, const ObsEvals& evals, Mat15d& H, Vec15d& g) {
  const AlignmentParams& P = *pr.params;
  H.setZero();
  g.setZero();
  for (std::size_t j = 0; j < pr.obs.size(); ++j) {
    const Obs& o = pr.obs[j];
    const TagEval& e = evals[j].e;
    const double r = evals[j].r;
    const Eigen::Matrix<double, 1, 15> Jr = rowJacobian(s, o, e, -o.inv_sigma * evals[j].grad.transpose());
    const double w = weightOf(pr, o, r);
    addOuterLower(H, Jr, w);
    g.noalias() += w * Jr.transpose() * r;
    if (!onBand(o)) continue;
    const double jb = P.band.derivative(e.tag.z());
    if (jb != 0.0) {
      const Eigen::Matrix<double, 1, 15> Jb = rowJacobian(s, o, e, jb * Vec3::UnitZ());
      addOuterLower(H, Jb, 1.0);
      g.noalias() += Jb.transpose() * P.band.residual(e.tag.z());
    }
  }
  H.triangularView<Eigen::StrictlyUpper>() = H.transpose();
  // Bias priors.
  const double ia = 1.0 / P.accel_bias_sigma, ig = 1.0 / P.gyro_bias_sigma;
  for (int k = 0; k < 3; ++k) {
    H(kBa + k, kBa + k) += ia * ia;
    g(kBa + k) += ia * ia * s.b.accel(k);
    H(kBg + k, kBg + k) += ig * ig;
    g(kBg + k) += ig * ig * s.b.gyro(k);
  }
  // Tilt prior: r = (R^T e_z - up_b) / sigma; under R Exp(phi), d(R^T e_z)/d phi = hat(R^T e_z).
  const Vec3 up = s.R.transpose() * Vec3::UnitZ();
  const double it = 1.0 / pr.gravity->tilt_sigma_rad;
  const Mat3 Jt = it * so3::hat(up);
  const Vec3 rt = it * (up - pr.gravity->up_b);
  H.block<3, 3>(kRot, kRot) += Jt.transpose() * Jt;
  g.segment<3>(kRot) += Jt.transpose() * rt;
  if (std::isfinite(P.vertical_velocity_sigma_m_s)) {
    const double iv = 1.0 / P.vertical_velocity_sigma_m_s;
    H(kVel + 2, kVel + 2) += iv * iv;
    g(kVel + 2) += iv * iv * s.v.z();
  }
}

State retract(const State& s, const Vec15d& dx) {
  State n;
  n.R = so3::normalize(s.R * so3::exp(dx.segment<3>(kRot)));
  n.p = s.p + dx.segment<3>(kPos);
  n.v = s.v + dx.segment<3>(kVel);
  n.b = ImuBias(s.b.accel + dx.segment<3>(kBa), s.b.gyro + dx.segment<3>(kBg));
  return n;
}

struct Fit {
  State s;
  Costs cost;
  Mat15d H = Mat15d::Zero();
};

/// `evals` and `candidate`: scratch buffers, reused across hypotheses.
Fit solve(const Problem& pr, const State& s0, ObsEvals& evals, ObsEvals& candidate) {
  Fit f;
  f.s = s0;
  f.cost = costOf(pr, f.s, &evals);
  double lambda = 1e-4;
  Vec15d g;
  for (int it = 0; it < pr.params->max_iterations; ++it) {
    linearize(pr, f.s, evals, f.H, g);
    bool accepted = false, converged = false;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Mat15d A = f.H;
      A.diagonal() += lambda * (f.H.diagonal().array() + 1e-9).matrix();
      const Vec15d dx = A.ldlt().solve(-g);
      if (!dx.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      const State s1 = retract(f.s, dx);
      const Costs c1 = costOf(pr, s1, &candidate, f.cost.total);
      if (c1.total <= f.cost.total) {
        evals.swap(candidate);
        converged = dx.cwiseAbs().maxCoeff() < 1e-6 || f.cost.total - c1.total < 1e-9 * (1.0 + f.cost.total);
        f.s = s1;
        f.cost = c1;
        lambda = std::max(1e-12, lambda * 0.2);
        accepted = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted || converged) break;
  }
  // f.H is at the state before the last accepted step: refreshed by
  // finishFit for the one fit whose covariance is used.
  return f;
}

void finishFit(const Problem& pr, Fit& f, ObsEvals& evals) {
  Vec15d g;
  (void)costOf(pr, f.s, &evals);
  linearize(pr, f.s, evals, f.H, g);
}

double wrapAngle(double a) { return std::remainder(a, 2.0 * M_PI); }

}  // namespace

double noiseScaleFromInlierShare(int inliers, int total, double bound) {
  if (total <= 0) return 1.0;
  const auto share_within = [](double k) { return std::erf(k / std::sqrt(2.0)); };  // P(|N(0, 1)| <= k)
  const double share = std::clamp(static_cast<double>(inliers) / total, 0.5, share_within(bound));
  // Solve share_within(k) = share for k (increasing in k): bisection, k in [0.6745, bound].
  double lo = 0.6, hi = bound;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (share_within(mid) < share ? lo : hi) = mid;
  }
  return bound / (0.5 * (lo + hi));
}

double AlignmentResult::noiseScale() const { return noiseScaleFromInlierShare(inliers, measurements); }

AlignmentResult alignRangeInertial(std::span<const ImuSample> imu, std::span<const RangeSample> ranges,
                                   std::int64_t t_ref_ns, const std::vector<Vec3>& p_w_anchors,
                                   const GravityAlignment& gravity, const Vec3& p_w_tag_guess,
                                   const Vec3& v_w_guess, const AlignmentParams& params) {
  std::vector<Measurement> measurements;
  measurements.reserve(ranges.size());
  for (const RangeSample& r : ranges) measurements.push_back(Measurement::of(r));
  return alignRangeInertial(imu, measurements, t_ref_ns, p_w_anchors, gravity, p_w_tag_guess, v_w_guess, params);
}

AlignmentResult alignRangeInertial(std::span<const ImuSample> imu, std::span<const Measurement> measurements,
                                   std::int64_t t_ref_ns, const std::vector<Vec3>& p_w_anchors,
                                   const GravityAlignment& gravity, const Vec3& p_w_tag_guess,
                                   const Vec3& v_w_guess, const AlignmentParams& params) {
  AlignmentResult out;
  out.t_ref_ns = t_ref_ns;
  if (!gravity.valid) {
    out.message = "no gravity alignment";
    return out;
  }
  if (!p_w_tag_guess.allFinite() || !v_w_guess.allFinite()) {
    out.message = "no finite position guess";
    return out;
  }
  auto usable = [&](const Measurement& m) {
    if (m.t_ns < t_ref_ns || !std::isfinite(m.value_m)) return false;
    switch (m.kind) {
      case Measurement::Kind::kRange: return m.anchor < p_w_anchors.size();
      case Measurement::Kind::kTdoa:
        return m.anchor < p_w_anchors.size() && m.anchor_b < p_w_anchors.size() && m.anchor != m.anchor_b;
      case Measurement::Kind::kUltrasonic: return m.anchor < params.p_w_ultrasonic.size();
    }
    return false;
  };
  std::vector<const Measurement*> used;
  std::vector<std::int64_t> times;
  for (const Measurement& m : measurements) {
    if (!usable(m)) continue;
    used.push_back(&m);
    times.push_back(m.t_ns);
  }
  if (used.empty() || imu.empty()) {
    out.message = "no measurements or no IMU samples";
    return out;
  }
  // Measurements are in time order (the caller's buffer); keep the queries ascending regardless.
  if (!std::is_sorted(times.begin(), times.end())) {
    out.message = "measurements not in time order";
    return out;
  }
  const std::vector<StrapdownDelta> deltas = integrateStrapdown(imu, t_ref_ns, times);

  Problem pr;
  pr.params = &params;
  pr.gravity = &gravity;
  pr.g_w = Vec3(0.0, 0.0, -params.gravity_m_s2);
  pr.loss.long_side = params.long_side_loss;
  if (!pr.loss.long_side) {
    RangeNoiseParams np;
    np.sigma_m = params.range_sigma_m;
    pr.loss.long_side = makeRangeLoss("asymmetric", np);
  }
  pr.loss.short_side_k = params.short_side_huber_k;
  pr.obs.reserve(used.size());
  for (std::size_t j = 0; j < used.size(); ++j) {
    const Measurement& m = *used[j];
    const Vec3* p_b_antenna =
        m.kind == Measurement::Kind::kRange ? &leverArmOf(params.tag_lever_arms, m.tag, params.p_b_tag) : &params.p_b_tag;
    Obs o{m.kind, Vec3::Zero(), Vec3::Zero(), m.value_m, 1.0 / params.range_sigma_m, p_b_antenna, &deltas[j]};
    if (m.kind == Measurement::Kind::kUltrasonic) {
      o.a = params.p_w_ultrasonic[m.anchor];
      o.inv_sigma = 1.0 / params.ultrasonic_sigma_m;
      o.p_b_sensor = &params.p_b_ultrasonic;
    } else {
      o.a = p_w_anchors[m.anchor];
      if (m.kind == Measurement::Kind::kTdoa) {
        o.b = p_w_anchors[m.anchor_b];
        o.inv_sigma = 1.0 / params.tdoa_sigma_m;
      }
    }
    pr.obs.push_back(o);
  }
  out.measurements = static_cast<int>(pr.obs.size());

  std::vector<Fit> fits;
  ObsEvals evals, candidate;
  for (int k = 0; k < params.yaw_hypotheses; ++k) {
    State s0;
    s0.R = yawRotation(2.0 * M_PI * k / params.yaw_hypotheses) * gravity.R_w_b;
    s0.p = p_w_tag_guess - s0.R * params.p_b_tag;
    s0.v = v_w_guess;
    fits.push_back(solve(pr, s0, evals, candidate));
    out.hypothesis_costs.push_back(fits.back().cost.total);
  }
  std::size_t best = 0;
  for (std::size_t k = 1; k < fits.size(); ++k) {
    if (fits[k].cost.total < fits[best].cost.total) best = k;
  }
  finishFit(pr, fits[best], evals);
  const Fit& f = fits[best];
  if (!std::isfinite(f.cost.total) || !f.s.R.allFinite() || !f.s.p.allFinite() || !f.s.v.allFinite()) {
    out.message = "alignment diverged";
    return out;
  }
  const double yaw_best = yawOf(f.s.R);
  for (std::size_t k = 0; k < fits.size(); ++k) {
    if (k == best || !std::isfinite(fits[k].cost.total)) continue;
    if (std::abs(wrapAngle(yawOf(fits[k].s.R) - yaw_best)) < params.distinct_yaw_rad) continue;
    out.second_cost_gap = std::min(out.second_cost_gap, fits[k].cost.total - f.cost.total);
  }

  out.T_w_b = Pose3(f.s.R, f.s.p);
  out.v_w = f.s.v;
  out.bias = f.s.b;
  out.cost = f.cost.total;
  out.measurement_cost = f.cost.measurements;

  const Eigen::SelfAdjointEigenSolver<Mat15d> eig(f.H);
  if (eig.eigenvalues().minCoeff() > 1e-12) {
    const Mat15d cov =
        eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
    // World-frame rotation perturbation: R Exp(phi) = Exp(R phi) R.
    const Mat3 cov_rot_w = f.s.R * cov.block<3, 3>(kRot, kRot) * f.s.R.transpose();
    out.yaw_sigma_rad = std::sqrt(std::max(0.0, cov_rot_w(2, 2)));
    out.position_sigma_m = std::sqrt(std::max(0.0, cov.block<3, 3>(kPos, kPos).trace()));
    // At the newest measurement: R_end = R_r dR(b_g), whose world perturbation is
    // R_r phi + R_end dR_dbg delta_b_g (dR(b) ~= dR Exp(dR_dbg b_g)).
    const StrapdownDelta& d_end = deltas.back();
    const Mat3 R_end = f.s.R * d_end.corrected(f.s.b).dR;
    Eigen::Matrix<double, 1, 15> j_yaw_end = Eigen::Matrix<double, 1, 15>::Zero();
    j_yaw_end.segment<3>(kRot) = f.s.R.row(2);
    j_yaw_end.segment<3>(kBg) = (R_end * d_end.dR_dbg).row(2);
    out.yaw_sigma_end_rad = std::sqrt(std::max(0.0, (j_yaw_end * cov * j_yaw_end.transpose())(0, 0)));
  }

  // Excitation of the fitted track.
  const Vec3 tag0 = out.T_w_b.transformFrom(params.p_b_tag);
  for (std::size_t j = 0; j < pr.obs.size(); ++j) {
    const StrapdownState st = out.at(deltas[j], params.gravity_m_s2);
    const Vec3 tag = st.T_w_b.transformFrom(params.p_b_tag);
    out.moved_m = std::max(out.moved_m, (tag - tag0).head<2>().norm());
    out.horizontal_dv_m_s = std::max(out.horizontal_dv_m_s, (st.v_w - out.v_w).head<2>().norm());
    const Obs& o = pr.obs[j];
    const double r = (o.value_m - o.predict(st.T_w_b.transformFrom(*o.p_b_sensor), nullptr)) * o.inv_sigma;
    if (std::abs(r) <= 3.0) ++out.inliers;
    if (o.kind == Measurement::Kind::kRange) {
      ++out.ranges;
      if (r < -kShortRangeSigmas) ++out.short_ranges;
    }
  }
  out.valid = true;
  return out;
}

}  // namespace rilo
