#include "hal/bmi263/sensor_time_fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "hal/bmi263/bmi263_registers.h"

namespace rilo::bmi263 {

void SensorTimeFitConfig::validate() const {
  auto fail = [](const std::string& what) { throw std::invalid_argument("SensorTimeFitConfig." + what); };
  if (window < 2) fail("window: need at least 2 points");
  if (max_span_ticks <= 0) fail("max_span_ticks: must be positive");
  if (min_span_ticks <= 0 || min_span_ticks > max_span_ticks) fail("min_span_ticks: must be in (0, max_span_ticks]");
  if (refit_every < 1) fail("refit_every: must be at least 1");
  if (!(max_rate_error > 0.0 && max_rate_error < 0.5)) fail("max_rate_error: must be in (0, 0.5)");
  if (negative_outlier_ns <= 0) fail("negative_outlier_ns: must be positive");
  if (positive_step_ns <= 0) fail("positive_step_ns: must be positive");
  if (reset_after < 1) fail("reset_after: must be at least 1");
}

std::int64_t SensorTimeUnwrapper::unwrap(std::uint32_t raw24, std::int64_t host_ns) noexcept {
  raw24 &= kSensorTimeMask;
  if (!has_last_) {
    has_last_ = true;
    last_tick_ = raw24;
  } else {
    const std::int64_t delta_mod = static_cast<std::int64_t>((raw24 - last_raw_) & kSensorTimeMask);
    const double elapsed_ticks = static_cast<double>(host_ns - last_host_ns_) / kSensorTimeTickNs;
    // Whole wraps not visible in the 24 bits, from the host clock.
    const auto wraps = std::llround((elapsed_ticks - static_cast<double>(delta_mod)) /
                                    static_cast<double>(kSensorTimeModulus));
    last_tick_ += delta_mod + static_cast<std::int64_t>(wraps) * kSensorTimeModulus;
  }
  last_raw_ = raw24;
  last_host_ns_ = host_ns;
  return last_tick_;
}

SensorTimeFit::SensorTimeFit(SensorTimeFitConfig config) : config_(config) {
  config_.validate();
  points_.resize(config_.window);
  hull_x_.resize(config_.window);
  hull_y_.resize(config_.window);
}

void SensorTimeFit::reset() noexcept {
  head_ = 0;
  count_ = 0;
  since_refit_ = 0;
  consecutive_rejected_ = 0;
  consecutive_high_ = 0;
  has_fit_ = false;
  slope_fitted_ = false;
  rate_out_of_bounds_ = false;
}

void SensorTimeFit::push(const Point& p) noexcept {
  if (count_ == points_.size()) popOldest();
  while (count_ > 0 && p.tick - at(0).tick > config_.max_span_ticks) popOldest();
  points_[(head_ + count_) % points_.size()] = p;
  ++count_;
}

void SensorTimeFit::popOldest() noexcept {
  head_ = (head_ + 1) % points_.size();
  --count_;
}

std::int64_t SensorTimeFit::hostTimeNs(std::int64_t tick) const noexcept {
  const double dt_ns = offset_ns_ + slope_ns_per_tick_ * static_cast<double>(tick - ref_tick_);
  return ref_host_ns_ + static_cast<std::int64_t>(std::llround(dt_ns));
}

double SensorTimeFit::ratePpm() const noexcept {
  if (!has_fit_ || slope_ns_per_tick_ <= 0.0) return 0.0;
  return (kSensorTimeTickNs / slope_ns_per_tick_ - 1.0) * 1e6;
}

SensorTimeFit::AddResult SensorTimeFit::add(std::int64_t tick, std::int64_t host_ns) noexcept {
  if (count_ > 0 && tick <= at(count_ - 1).tick) return AddResult::kRejectedOrder;
  const Point point{tick, host_ns};
  if (has_fit_ && slope_fitted_) {
    const std::int64_t residual_ns = host_ns - hostTimeNs(tick);
    if (residual_ns < -config_.negative_outlier_ns) {
      // Impossible with one-sided latency: a glitch or a mis-paired edge.
      // Many in a row mean the relation itself changed: start over.
      if (++consecutive_rejected_ < config_.reset_after) return AddResult::kRejectedOutlier;
      reset();
      push(point);
      refit();
      return AddResult::kReset;
    }
    consecutive_rejected_ = 0;
    if (residual_ns > config_.positive_step_ns) {
      if (++consecutive_high_ >= config_.reset_after) {
        reset();
        push(point);
        refit();
        return AddResult::kReset;
      }
    } else {
      consecutive_high_ = 0;
    }
  }
  push(point);
  ++since_refit_;
  if (!slope_fitted_ || since_refit_ >= config_.refit_every) refit();
  return AddResult::kAccepted;
}

void SensorTimeFit::refit() noexcept {
  since_refit_ = 0;
  if (count_ == 0) return;
  // Coordinates relative to the newest point and to the nominal line keep the
  // numbers small (microseconds), so doubles lose nothing.
  const Point& newest = at(count_ - 1);
  ref_tick_ = newest.tick;
  ref_host_ns_ = newest.host_ns;
  double min_y = std::numeric_limits<double>::infinity();
  double sum_x = 0.0;
  std::size_t hull_size = 0;
  for (std::size_t i = 0; i < count_; ++i) {
    const Point& p = at(i);
    const double x = static_cast<double>(p.tick - ref_tick_);
    const double y = static_cast<double>(p.host_ns - ref_host_ns_) - kSensorTimeTickNs * x;
    min_y = std::min(min_y, y);
    sum_x += x;
    // Lower hull, monotone chain (x strictly increasing): drop the last
    // vertex while it is not strictly below the chord to the new point.
    while (hull_size >= 2) {
      const double ox = hull_x_[hull_size - 2];
      const double oy = hull_y_[hull_size - 2];
      const double ax = hull_x_[hull_size - 1];
      const double ay = hull_y_[hull_size - 1];
      const double cross = (ax - ox) * (y - oy) - (ay - oy) * (x - ox);
      if (cross > 0.0) break;
      --hull_size;
    }
    hull_x_[hull_size] = x;
    hull_y_[hull_size] = y;
    ++hull_size;
  }
  has_fit_ = true;
  slope_fitted_ = false;
  slope_ns_per_tick_ = kSensorTimeTickNs;
  offset_ns_ = min_y;  // lower envelope with the nominal slope
  const std::int64_t span_ticks = newest.tick - at(0).tick;
  if (span_ticks < config_.min_span_ticks || hull_size < 2) return;

  // The LP optimum: the hull edge over the mean tick.
  const double mean_x = sum_x / static_cast<double>(count_);
  std::size_t edge = 0;
  while (edge + 2 < hull_size && hull_x_[edge + 1] < mean_x) ++edge;
  const double dx = hull_x_[edge + 1] - hull_x_[edge];
  const double dslope = (hull_y_[edge + 1] - hull_y_[edge]) / dx;
  if (std::abs(dslope) > config_.max_rate_error * kSensorTimeTickNs) {
    rate_out_of_bounds_ = true;  // keep the nominal-slope envelope
    return;
  }
  rate_out_of_bounds_ = false;
  slope_fitted_ = true;
  slope_ns_per_tick_ = kSensorTimeTickNs + dslope;
  offset_ns_ = hull_y_[edge] - dslope * hull_x_[edge];
}

}  // namespace rilo::bmi263
