#include "estimation/noise/asymmetric_loss.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace rilo {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kLogSqrt2Pi = 0.91893853320467274178;  // log(sqrt(2 pi)) = -log(phi(0))

// Gauss-Kronrod 7/15 rule on [-1, 1] (QUADPACK qk15): Kronrod abscissae
// (descending, last is the centre), Kronrod weights, Gauss weights of the
// odd-indexed abscissae and the centre.
constexpr std::array<double, 8> kXgk = {
    0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
    0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
    0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
    0.207784955007898467600689403773245, 0.0};
constexpr std::array<double, 8> kWgk = {
    0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
    0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
    0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
    0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
constexpr std::array<double, 4> kWg = {
    0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
    0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

// Integrals over the half-Cauchy measure of the Gaussian kernel, scaled by
// exp(eps_neg^2 / 2) (eps_neg = min(eps, 0)) so nothing underflows:
//   i0 = 2/pi int_0^{pi/2} E(c(theta)) dtheta,  i1 = 2/pi int (eps - c) E dtheta,
//   E(c) = exp(-((eps - c)^2 - eps_neg^2) / 2) <= 1.
// g = i0 * phi(eps_neg) and g'/g = -i1 / i0.
struct Moments {
  double i0 = 0.0;
  double i1 = 0.0;
};

class ConvolutionQuadrature {
 public:
  ConvolutionQuadrature(double gamma, double eps)
      : gamma_(gamma), eps_(eps), eps_neg2_(eps < 0.0 ? eps * eps : 0.0) {}

  /// Log of the density and d log g / d eps.
  void compute(double* log_g, double* dlog_g) {
    // The kernel is sharp (width 1 in c, i.e. ~cos^2(theta)/gamma in theta)
    // and sits at c = eps; start from panels whose edges bracket it at several
    // widths, plus the Cauchy scale and small c for eps < 0, so no peak is
    // missed. theta in [0, pi/4] (c <= gamma, c = gamma tan theta) and
    // u = pi/2 - theta in [0, pi/4] (c >= gamma, c = gamma / tan u) are two
    // charts: near theta = pi/2 tan() of a rounded theta would lose c.
    std::vector<double> c_breaks;
    for (double k : {-16.0, -8.0, -4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0}) {
      c_breaks.push_back(eps_ + k);
    }
    for (int j = -6; j <= 6; ++j) c_breaks.push_back(gamma_ * std::ldexp(1.0, j));
    for (int j = -8; j <= 2; ++j) c_breaks.push_back(std::ldexp(1.0, j));
    std::vector<double> theta_breaks = {0.0, kPi / 4};
    std::vector<double> u_breaks = {0.0, kPi / 4};
    for (double c : c_breaks) {
      if (!(c > 0.0) || !std::isfinite(c)) continue;
      if (c <= gamma_) {
        theta_breaks.push_back(std::atan(c / gamma_));
      } else {
        u_breaks.push_back(std::atan(gamma_ / c));
      }
    }
    std::sort(theta_breaks.begin(), theta_breaks.end());
    std::sort(u_breaks.begin(), u_breaks.end());

    // Coarse pass over the initial panels sets the absolute tolerance, then
    // each panel is refined by bisection from its coarse estimate.
    struct Initial {
      bool u_chart;
      double a, b;
      Panel p;
    };
    std::vector<Initial> initial;
    double coarse_i0 = 0.0;
    forEachPanel(theta_breaks, u_breaks, [&](bool u_chart, double a, double b) {
      initial.push_back({u_chart, a, b, gk15(u_chart, a, b)});
      coarse_i0 += initial.back().p.k.i0;
    });
    tol_ = 1e-14 * coarse_i0;
    Moments total;
    for (const Initial& in : initial) {
      const Moments m = adapt(in.u_chart, in.a, in.b, in.p, 0);
      total.i0 += m.i0;
      total.i1 += m.i1;
    }
    total.i0 *= 2.0 / kPi;
    total.i1 *= 2.0 / kPi;
    *log_g = std::log(total.i0) - kLogSqrt2Pi - 0.5 * eps_neg2_;
    *dlog_g = -total.i1 / total.i0;
  }

 private:
  struct Panel {
    Moments k;       ///< Kronrod estimate
    double err = 0;  ///< max |Kronrod - Gauss| over both moments
  };

  template <class F>
  static void forEachPanel(const std::vector<double>& theta_breaks, const std::vector<double>& u_breaks, F&& f) {
    for (std::size_t i = 0; i + 1 < theta_breaks.size(); ++i) {
      if (theta_breaks[i + 1] > theta_breaks[i]) f(false, theta_breaks[i], theta_breaks[i + 1]);
    }
    for (std::size_t i = 0; i + 1 < u_breaks.size(); ++i) {
      if (u_breaks[i + 1] > u_breaks[i]) f(true, u_breaks[i], u_breaks[i + 1]);
    }
  }

  Moments integrand(bool u_chart, double x) const {
    const double c = u_chart ? gamma_ / std::tan(x) : gamma_ * std::tan(x);
    if (!(c < 1e150)) return {};
    const double d = eps_ - c;
    const double e = std::exp(-0.5 * (d * d - eps_neg2_));
    return {e, d * e};
  }

  Panel gk15(bool u_chart, double a, double b) const {
    const double centre = 0.5 * (a + b);
    const double half = 0.5 * (b - a);
    const Moments fc = integrand(u_chart, centre);
    Moments k{kWgk[7] * fc.i0, kWgk[7] * fc.i1};
    Moments g{kWg[3] * fc.i0, kWg[3] * fc.i1};
    for (std::size_t j = 0; j < 7; ++j) {
      const Moments f1 = integrand(u_chart, centre - half * kXgk[j]);
      const Moments f2 = integrand(u_chart, centre + half * kXgk[j]);
      k.i0 += kWgk[j] * (f1.i0 + f2.i0);
      k.i1 += kWgk[j] * (f1.i1 + f2.i1);
      if (j % 2 == 1) {
        g.i0 += kWg[j / 2] * (f1.i0 + f2.i0);
        g.i1 += kWg[j / 2] * (f1.i1 + f2.i1);
      }
    }
    Panel p;
    p.k = {k.i0 * half, k.i1 * half};
    p.err = half * std::max(std::abs(k.i0 - g.i0), std::abs(k.i1 - g.i1));
    return p;
  }

  Moments adapt(bool u_chart, double a, double b, const Panel& p, int depth) const {
    if (p.err <= tol_ || depth >= 48) return p.k;
    const double m = 0.5 * (a + b);
    const Moments l = adapt(u_chart, a, m, gk15(u_chart, a, m), depth + 1);
    const Moments r = adapt(u_chart, m, b, gk15(u_chart, m, b), depth + 1);
    return {l.i0 + r.i0, l.i1 + r.i1};
  }

  double gamma_;
  double eps_;
  double eps_neg2_;
  double tol_ = 0.0;
};

// Bisection for the sign change of a continuous f with f(lo) < 0 <= f(hi),
// down to adjacent doubles.
template <class F>
double bisect(F&& f, double lo, double hi) {
  for (int it = 0; it < 2000; ++it) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;
    (f(mid) < 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

double AsymmetricLoss::convolvedDensityByQuadrature(double gamma, double eps) {
  if (!(gamma > 0.0) || !std::isfinite(gamma)) {
    throw std::invalid_argument("convolvedDensityByQuadrature: gamma must be finite and > 0");
  }
  double log_g = 0.0;
  double dlog_g = 0.0;
  ConvolutionQuadrature(gamma, eps).compute(&log_g, &dlog_g);
  return std::exp(log_g);
}

AsymmetricLoss::AsymmetricLoss(double gamma, double nlos_weight, Component component)
    : gamma_(gamma), w_(nlos_weight), component_(component) {
  if (!(gamma >= kMinGamma && gamma <= kMaxGamma)) {
    throw std::invalid_argument("AsymmetricLoss: gamma (whitened half-Cauchy scale gamma_m / sigma_m) must be in [" +
                                std::to_string(kMinGamma) + ", " + std::to_string(kMaxGamma) + "], got " +
                                std::to_string(gamma));
  }
  // w < 1/2 is what makes rho exactly Gaussian for r <= 0: there g <= phi, so
  // w g < (1 - w) phi.
  if (!(nlos_weight > 0.0 && nlos_weight < 0.5)) {
    throw std::invalid_argument("AsymmetricLoss: nlos_weight (NLOS prior w) must be in (0, 0.5), got " +
                                std::to_string(nlos_weight));
  }
  nlos_offset_ = -kLogSqrt2Pi + std::log((1.0 - w_) / w_);
  log_asym_a_ = std::log(2.0 * gamma_ / kPi);

  if (component_ == Component::kConvolved) {
    const double s_max = std::asinh(kTableMaxEps);
    s_min_ = std::asinh(kTableMinEps);
    const double ds = (s_max - s_min_) / (kTableNodes - 1);
    inv_ds_ = 1.0 / ds;
    table_.resize(kTableNodes);
    for (int i = 0; i < kTableNodes; ++i) {
      const double s = s_min_ + i * ds;
      const double eps = std::sinh(s);
      double log_g = 0.0;
      double dlog_g = 0.0;
      ConvolutionQuadrature(gamma_, eps).compute(&log_g, &dlog_g);
      // d(-log g)/ds = d(-log g)/deps * cosh(s).
      table_[static_cast<std::size_t>(i)] = {-log_g, -dlog_g * std::cosh(s) * ds};
    }
    table_max_eps_ = std::sinh(s_min_ + (kTableNodes - 1) * ds);
    // Mode of g: -log g decreases up to it (d(-log g)/deps = eps - E[c | eps]
    // < 0 at eps <= 0) and increases beyond (g is unimodal: a Gaussian, which is
    // strongly unimodal, convolved with the unimodal half-Cauchy).
    const auto slope = [this](double eps) {
      double d = 0.0;
      tableNegLogDensity(eps, &d);
      return d;
    };
    double hi = 1.0;
    while (slope(hi) < 0.0 && hi < kTableMaxEps) hi *= 2.0;
    eps_m_ = bisect(slope, 0.0, hi);
    for (int i = 0; i < kTableNodes; ++i) {
      const double eps = std::sinh(s_min_ + i * ds);
      if (eps > eps_m_ + 1e-6 && table_[static_cast<std::size_t>(i)].slope_h < -1e-12) {
        throw std::logic_error("AsymmetricLoss: convolved NLOS density is not unimodal (table error)");
      }
    }
  } else {
    eps_m_ = 0.0;
    // rho_NLOS(0) > rho_LOS(0) = 0 is needed for a Gaussian core at 0.
    if (!(halfCauchyNegLogDensity(0.0, nullptr) + nlos_offset_ > 0.0)) {
      const double gamma_min = 2.0 * w_ / (kPi * (1.0 - w_)) * std::exp(kLogSqrt2Pi);
      throw std::invalid_argument(
          "AsymmetricLoss: gamma too small for the half-Cauchy component with nlos_weight " + std::to_string(w_) +
          ": the NLOS density 2/(pi gamma) at 0 beats the LOS one; need gamma > " + std::to_string(gamma_min) +
          " (or use the convolved component)");
    }
  }

  // Decision point: the single root of rho_LOS - rho_NLOS (clamped at the mode).
  const auto los_minus_nlos = [this](double eps) {
    return 0.5 * eps * eps - (negLogDensity(std::max(eps, eps_m_), nullptr) + nlos_offset_);
  };
  if (!(los_minus_nlos(0.0) < 0.0)) {
    throw std::logic_error("AsymmetricLoss: NLOS component beats LOS at 0 (should be impossible for w < 0.5)");
  }
  double hi = 1.0;
  while (los_minus_nlos(hi) < 0.0) hi *= 2.0;
  eps_d_ = bisect(los_minus_nlos, 0.0, hi);
}

std::string AsymmetricLoss::name() const {
  return component_ == Component::kConvolved ? "asymmetric" : "asymmetric-half-cauchy";
}

double AsymmetricLoss::loss(double r) const {
  if (r <= eps_d_) return 0.5 * r * r;
  return negLogDensity(std::max(r, eps_m_), nullptr) + nlos_offset_;
}

double AsymmetricLoss::derivative(double r) const {
  if (r <= eps_d_) return r;
  if (r < eps_m_) return 0.0;  // flat clamped stretch (only if eps_m > eps_d)
  double d = 0.0;
  negLogDensity(r, &d);
  return d;
}

double AsymmetricLoss::weight(double r) const {
  if (r <= eps_d_) return 1.0;
  return derivative(r) / r;
}

double AsymmetricLoss::nlosLoss(double r) const { return negLogDensity(r, nullptr) + nlos_offset_; }

double AsymmetricLoss::nlosNegLogDensity(double eps, double* d_deps) const {
  if (component_ == Component::kHalfCauchy || eps >= kTableMinEps) return negLogDensity(eps, d_deps);
  // Far on the short side g is the Gaussian's tail times a slowly varying
  // factor: -log g ~ eps^2 / 2 + a log(-eps) + b, with a and b matching the
  // table's value and slope at its end (a -> 1 for the exact asymptote).
  double d0 = 0.0;
  const double f0 = negLogDensity(kTableMinEps, &d0);
  const double e0 = kTableMinEps;
  const double a = e0 * (d0 - e0);
  if (d_deps != nullptr) *d_deps = eps + a / eps;
  return f0 + 0.5 * (eps * eps - e0 * e0) + a * std::log(eps / e0);
}

double AsymmetricLoss::nlosDensity(double eps) const { return std::exp(-negLogDensity(eps, nullptr)); }

double AsymmetricLoss::negLogDensity(double eps, double* d_deps) const {
  if (component_ == Component::kHalfCauchy) return halfCauchyNegLogDensity(eps, d_deps);
  if (eps >= kTableMinEps && eps <= table_max_eps_) return tableNegLogDensity(eps, d_deps);
  if (eps > table_max_eps_) return asymptoteNegLogDensity(eps, d_deps);
  if (eps < kTableMinEps) {  // slow path, never taken by loss()
    double log_g = 0.0;
    double dlog_g = 0.0;
    ConvolutionQuadrature(gamma_, eps).compute(&log_g, &dlog_g);
    if (d_deps != nullptr) *d_deps = -dlog_g;
    return -log_g;
  }
  if (d_deps != nullptr) *d_deps = eps;  // NaN
  return eps;
}

double AsymmetricLoss::tableNegLogDensity(double eps, double* d_deps) const {
  // s = asinh(eps), sharing sqrt(1 + eps^2) with ds/deps.
  const double q = std::sqrt(1.0 + eps * eps);
  const double s = std::copysign(std::log(std::abs(eps) + q), eps);
  const double t = (s - s_min_) * inv_ds_;
  const int i = std::clamp(static_cast<int>(t), 0, kTableNodes - 2);
  const double tau = t - i;
  const Node& a = table_[static_cast<std::size_t>(i)];
  const Node& b = table_[static_cast<std::size_t>(i) + 1];
  // Cubic Hermite in tau: C1 across nodes since node slopes are exact derivatives.
  const double tau2 = tau * tau;
  const double tau3 = tau2 * tau;
  const double h00 = 2 * tau3 - 3 * tau2 + 1;
  const double h10 = tau3 - 2 * tau2 + tau;
  const double h01 = 3 * tau2 - 2 * tau3;
  const double h11 = tau3 - tau2;
  if (d_deps != nullptr) {
    const double dh00 = 6 * tau2 - 6 * tau;
    const double dh10 = 3 * tau2 - 4 * tau + 1;
    const double dh11 = 3 * tau2 - 2 * tau;
    const double d_dtau = dh00 * (a.value - b.value) + dh10 * a.slope_h + dh11 * b.slope_h;
    *d_deps = d_dtau * inv_ds_ / q;
  }
  return h00 * a.value + h10 * a.slope_h + h01 * b.value + h11 * b.slope_h;
}

double AsymmetricLoss::asymptoteNegLogDensity(double eps, double* d_deps) const {
  // For eps >> 1, c = eps - n with n ~ N(0,1): g = h(eps) + h''(eps)/2 + O(h'''' ),
  // h the half-Cauchy density. With q = eps^2 + gamma^2:
  //   g  = (2 gamma/pi) / q * (1 + (3 eps^2 - gamma^2) / q^2),
  //   g' = -(2 gamma/pi) 2 eps / q^2 * (1 + 6 (eps^2 - gamma^2) / q^2),
  // written in rho2 = (gamma/eps)^2 so eps up to +inf stays finite.
  const double rho2 = (gamma_ / eps) * (gamma_ / eps);
  const double one_p = 1.0 + rho2;
  const double k = 1.0 / (eps * eps * one_p * one_p);
  const double corr_g = (3.0 - rho2) * k;
  if (d_deps != nullptr) {
    *d_deps = 2.0 / (eps * one_p) * (1.0 + 6.0 * (1.0 - rho2) * k) / (1.0 + corr_g);
  }
  return -log_asym_a_ + 2.0 * std::log(eps) + std::log1p(rho2) - std::log1p(corr_g);
}

double AsymmetricLoss::halfCauchyNegLogDensity(double eps, double* d_deps) const {
  if (eps < 0.0) {
    if (d_deps != nullptr) *d_deps = 0.0;
    return std::numeric_limits<double>::infinity();
  }
  // -log(2 / (pi gamma) / (1 + (eps/gamma)^2)); derivative 2 eps / (gamma^2 + eps^2).
  if (d_deps != nullptr) *d_deps = eps > 0.0 ? 2.0 / (eps + gamma_ * gamma_ / eps) : 0.0;
  const double x = eps / gamma_;
  return std::log(kPi * gamma_ / 2.0) + std::log1p(x * x);
}

}  // namespace rilo
