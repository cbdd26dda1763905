#include "estimation/noise/dynamic_covariance.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

namespace {

void validateKind(const NoiseKindParams& k, const std::string& where) {
  auto fail = [&](const char* field, const char* rule) {
    throw std::invalid_argument("DynamicCovarianceParams." + where + "." + field + " " + rule);
  };
  if (!(k.sigma_min_m > 0.0) || !std::isfinite(k.sigma_min_m)) fail("sigma_min_m", "must be finite and > 0");
  if (!std::isfinite(k.sigma_max_m) || !(k.sigma_max_m >= k.sigma_min_m)) {
    fail("sigma_max_m", "must be finite and >= sigma_min_m");
  }
  if (!(k.nominal_sigma_m >= k.sigma_min_m && k.nominal_sigma_m <= k.sigma_max_m)) {
    fail("nominal_sigma_m", "must be in [sigma_min_m, sigma_max_m]");
  }
}

/// splitmix64 finalizer: spreads consecutive anchor ids over the table.
std::uint64_t mix(std::uint64_t x) {
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ULL;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebULL;
  x ^= x >> 31;
  return x;
}

}  // namespace

void DynamicCovarianceParams::validate() const {
  validateKind(range, "range");
  validateKind(tdoa, "tdoa");
  validateKind(ultrasonic, "ultrasonic");
  auto fail = [](const char* field, const std::string& rule) {
    throw std::invalid_argument(std::string("DynamicCovarianceParams.") + field + " " + rule);
  };
  if (max_keys < 1 || max_keys > (1 << 20)) fail("max_keys", "must be in [1, 2^20]");
  if (!(window_samples >= 2.0) || !std::isfinite(window_samples)) fail("window_samples", "must be finite and >= 2");
  if (min_samples < 3 || min_samples > DynamicCovariance::kMaxWarmupSamples) {
    fail("min_samples", "must be in [3, " + std::to_string(DynamicCovariance::kMaxWarmupSamples) + "]");
  }
  if (!(huber_c > 0.0) || !std::isfinite(huber_c)) fail("huber_c", "must be finite and > 0");
}

double DynamicCovariance::consistency(double c) {
  // E[min(Z^2, c^2)] = P(|Z| < c) - 2 c phi(c) + c^2 P(|Z| >= c).
  const double p_in = std::erf(c / std::sqrt(2.0));
  const double phi = std::exp(-0.5 * c * c) / std::sqrt(2.0 * M_PI);
  return p_in - 2.0 * c * phi + c * c * (1.0 - p_in);
}

DynamicCovariance::DynamicCovariance(const DynamicCovarianceParams& params) : params_(params) {
  params_.validate();
  lambda_min_ = 1.0 / params_.window_samples;
  c2_ = params_.huber_c * params_.huber_c;
  inv_beta_ = 1.0 / consistency(params_.huber_c);
  const auto n = static_cast<std::size_t>(params_.max_keys);
  entries_.resize(n);
  warmup_.resize(n * static_cast<std::size_t>(params_.min_samples));
  slots_.assign(std::bit_ceil(2 * n), -1);
}

const NoiseKindParams& DynamicCovariance::kindParams(NoiseKind kind) const {
  switch (kind) {
    case NoiseKind::kTdoa:
      return params_.tdoa;
    case NoiseKind::kUltrasonic:
      return params_.ultrasonic;
    case NoiseKind::kRange:
    default:
      return params_.range;
  }
}

std::size_t DynamicCovariance::slotOf(const NoiseKey& key) const {
  const std::uint64_t packed = (static_cast<std::uint64_t>(key.b) << 32) | key.a;
  const std::uint64_t h = mix(packed ^ mix(static_cast<std::uint64_t>(key.kind) + 1));
  return static_cast<std::size_t>(h) & (slots_.size() - 1);
}

int DynamicCovariance::find(const NoiseKey& key) const {
  const std::size_t mask = slots_.size() - 1;
  for (std::size_t s = slotOf(key), probes = 0; probes < slots_.size(); s = (s + 1) & mask, ++probes) {
    const std::int32_t e = slots_[s];
    if (e < 0) return -1;
    if (entries_[static_cast<std::size_t>(e)].key == key) return e;
  }
  return -1;
}

void DynamicCovariance::finishWarmup(Entry& e, double* buffer) const {
  const NoiseKindParams& k = kindParams(e.key.kind);
  const int n0 = params_.min_samples;
  for (int i = 0; i < n0; ++i) buffer[i] = std::abs(buffer[i]);
  double* mid = buffer + n0 / 2;
  std::nth_element(buffer, mid, buffer + n0);
  double med = *mid;
  if (n0 % 2 == 0) med = 0.5 * (med + *std::max_element(buffer, mid));
  const double mad_sigma = 1.482602218505602 * med;  // 1 / Phi^-1(3/4)
  const double s2 = mad_sigma * mad_sigma - e.warm_p_sum / n0;
  e.s2 = std::clamp(s2, k.sigma_min_m * k.sigma_min_m, k.sigma_max_m * k.sigma_max_m);
}

CovarianceUpdate DynamicCovariance::update(const NoiseKey& key, double residual_m, double predicted_var_m2) {
  if (!std::isfinite(residual_m) || !std::isfinite(predicted_var_m2) || predicted_var_m2 < 0.0) {
    return CovarianceUpdate::kRejectedNonFinite;
  }
  // Find or insert (linear probing; the table never holds more than half
  // its slots, so an empty slot is always reached).
  const std::size_t mask = slots_.size() - 1;
  std::size_t s = slotOf(key);
  std::int32_t idx = -1;
  while (slots_[s] >= 0) {
    if (entries_[static_cast<std::size_t>(slots_[s])].key == key) {
      idx = slots_[s];
      break;
    }
    s = (s + 1) & mask;
  }
  if (idx < 0) {
    if (used_ >= entries_.size()) {
      ++dropped_;
      return CovarianceUpdate::kTableFull;
    }
    idx = static_cast<std::int32_t>(used_++);
    slots_[s] = idx;
    entries_[static_cast<std::size_t>(idx)] = Entry{key, 0, 0.0, 0.0};
  }
  Entry& e = entries_[static_cast<std::size_t>(idx)];
  const int n0 = params_.min_samples;
  double* buffer = warmup_.data() + static_cast<std::size_t>(idx) * static_cast<std::size_t>(n0);
  if (e.n < n0) {
    buffer[e.n] = residual_m;
    e.warm_p_sum += predicted_var_m2;
    ++e.n;
    if (e.n < n0) return CovarianceUpdate::kWarmingUp;
    finishWarmup(e, buffer);
    return CovarianceUpdate::kUpdated;
  }
  ++e.n;
  const NoiseKindParams& k = kindParams(key.kind);
  const double total2 = e.s2 + predicted_var_m2;                      // expected e^2
  const double z2 = residual_m * residual_m / total2;                 // standardized
  const double psi2 = std::min(z2, c2_) * inv_beta_;                  // clipped, E = 1 under N(0, 1)
  const double lambda = std::max(1.0 / static_cast<double>(e.n), lambda_min_);
  const double s2 = (1.0 - lambda) * e.s2 + lambda * (total2 * psi2 - predicted_var_m2);
  e.s2 = std::clamp(s2, k.sigma_min_m * k.sigma_min_m, k.sigma_max_m * k.sigma_max_m);
  return CovarianceUpdate::kUpdated;
}

double DynamicCovariance::sigma(const NoiseKey& key) const {
  const NoiseKindParams& k = kindParams(key.kind);
  const int i = find(key);
  if (i < 0) return k.nominal_sigma_m;
  const Entry& e = entries_[static_cast<std::size_t>(i)];
  if (e.n < params_.min_samples) return k.nominal_sigma_m;
  return std::sqrt(e.s2);
}

std::int64_t DynamicCovariance::samples(const NoiseKey& key) const {
  const int i = find(key);
  return i < 0 ? 0 : entries_[static_cast<std::size_t>(i)].n;
}

bool DynamicCovariance::estimated(const NoiseKey& key) const {
  const int i = find(key);
  return i >= 0 && entries_[static_cast<std::size_t>(i)].n >= params_.min_samples;
}

void DynamicCovariance::reset() {
  std::fill(slots_.begin(), slots_.end(), -1);
  used_ = 0;
  dropped_ = 0;
}

}  // namespace rilo
