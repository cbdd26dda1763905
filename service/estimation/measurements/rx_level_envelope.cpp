#include "estimation/measurements/rx_level_envelope.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo {

void RxLevelEnvelopeParams::validate() const {
  auto fail = [](const char* field, const char* rule) {
    throw std::invalid_argument(std::string("RxLevelEnvelopeParams.") + field + " " + rule);
  };
  if (window_ranges < 8 || window_ranges > RxLevelEnvelope::kCapacity) fail("window_ranges", "must be in [8, 4096]");
  if (min_ranges < 8 || min_ranges > window_ranges) fail("min_ranges", "must be in [8, window_ranges]");
  if (refit_every < 1) fail("refit_every", "must be >= 1");
  if (fit_iterations < 1 || fit_iterations > 20) fail("fit_iterations", "must be in [1, 20]");
  if (!(min_log10_span >= 0.0 && std::isfinite(min_log10_span))) fail("min_log10_span", "must be finite and >= 0");
  if (!(min_exponent > 0.0 && max_exponent >= min_exponent && std::isfinite(max_exponent))) {
    fail("min_exponent", "and max_exponent must be finite with 0 < min_exponent <= max_exponent");
  }
}

RxLevelEnvelope::RxLevelEnvelope(RxLevelEnvelopeParams params) : params_(params) { params_.validate(); }

double RxLevelEnvelope::log10Range(double range_m) noexcept {
  return std::log10(std::max(range_m, 0.3));  // ranges below 0.3 m are near-field and noise: one bin
}

void RxLevelEnvelope::add(double range_m, double rssi_dbm) noexcept {
  // One absurd value would poison the sums for a whole window.
  if (!params_.enabled || !(range_m > 0.0 && range_m < 1e4) || !(rssi_dbm >= -150.0 && rssi_dbm <= 0.0)) return;
  x_[static_cast<std::size_t>(next_)] = log10Range(range_m);
  y_[static_cast<std::size_t>(next_)] = rssi_dbm;
  next_ = (next_ + 1) % params_.window_ranges;
  filled_ = std::min(filled_ + 1, params_.window_ranges);
  ++since_fit_;
  if (filled_ >= params_.min_ranges && (!fitted_ || since_fit_ >= params_.refit_every)) refit();
}

double RxLevelEnvelope::losLevelDbm(double range_m) const noexcept {
  if (!fitted_ || !std::isfinite(range_m)) return std::numeric_limits<double>::quiet_NaN();
  return intercept_ + slope_ * log10Range(range_m) + los_level_;
}

double RxLevelEnvelope::deficitDb(double range_m, double rssi_dbm) const noexcept {
  const double los_dbm = losLevelDbm(range_m);
  if (!std::isfinite(los_dbm) || !std::isfinite(rssi_dbm)) return std::numeric_limits<double>::quiet_NaN();
  return std::max(0.0, los_dbm - rssi_dbm);
}

namespace {

/// The q-quantile (0..1) of the first n values of v (reorders them).
double quantile(double* v, int n, double q) noexcept {
  const int k = std::clamp(static_cast<int>(q * n), 0, n - 1);
  std::nth_element(v, v + k, v + n);
  return v[k];
}

}  // namespace

void RxLevelEnvelope::refit() noexcept {
  since_fit_ = 0;
  const int n = filled_;
  double* s = scratch_.data();
  std::copy_n(x_.begin(), n, s);
  const double x10 = quantile(s, n, 0.1), x90 = quantile(s, n, 0.9);
  const bool fit_slope = x90 - x10 >= params_.min_log10_span;
  const double slope_min = -10.0 * params_.max_exponent, slope_max = -10.0 * params_.min_exponent;
  double a = 0.0, b = std::clamp(-20.0, slope_min, slope_max);  // free space until the data say otherwise
  std::fill_n(keep_.begin(), n, std::uint8_t{1});
  for (int it = 0; it < params_.fit_iterations; ++it) {
    double sx = 0, sy = 0, sxx = 0, sxy = 0, m = 0;
    for (int i = 0; i < n; ++i) {
      if (!keep_[static_cast<std::size_t>(i)]) continue;
      const double xi = x_[static_cast<std::size_t>(i)], yi = y_[static_cast<std::size_t>(i)];
      sx += xi, sy += yi, sxx += xi * xi, sxy += xi * yi, m += 1;
    }
    const double var_x = sxx / m - (sx / m) * (sx / m);
    if (fit_slope && var_x > 1e-9) b = std::clamp((sxy / m - (sx / m) * (sy / m)) / var_x, slope_min, slope_max);
    a = sy / m - b * sx / m;
    for (int i = 0; i < n; ++i) s[i] = y_[static_cast<std::size_t>(i)] - (a + b * x_[static_cast<std::size_t>(i)]);
    if (it + 1 == params_.fit_iterations) break;  // the last line is kept: no new mask
    const double median = quantile(s, n, 0.5);
    for (int i = 0; i < n; ++i) {
      const double r = y_[static_cast<std::size_t>(i)] - (a + b * x_[static_cast<std::size_t>(i)]);
      keep_[static_cast<std::size_t>(i)] = r >= median ? 1 : 0;
    }
  }
  for (int i = 0; i < n; ++i) s[i] = y_[static_cast<std::size_t>(i)] - (a + b * x_[static_cast<std::size_t>(i)]);
  intercept_ = a;
  slope_ = b;
  los_level_ = quantile(s, n, 0.75);  // the upper half's median
  fitted_ = true;
}

void RxLevelEnvelope::reset() noexcept {
  next_ = filled_ = since_fit_ = 0;
  fitted_ = false;
  intercept_ = slope_ = los_level_ = 0.0;
}

}  // namespace rilo
