#include "hal/dw3000/anchor_scheduler.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace rilo::dw3000 {
namespace {

void require(bool ok, const char* parameter, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("AnchorScheduler: ") + parameter + " " + what);
}

}  // namespace

AnchorScheduler::AnchorScheduler(std::size_t anchor_count, const AnchorSchedulerParams& params)
    : params_(params), anchors_(anchor_count) {
  require(anchor_count >= 1, "anchor_count", "must be at least 1");
  require(params.max_active >= 1, "max_active", "must be at least 1");
  require(std::isfinite(params.range_rate_hz) && params.range_rate_hz > 0.0 && params.range_rate_hz <= 1000.0,
          "range_rate_hz", "must be in (0, 1000]");
  require(params.rediscovery_period_ns > 0, "rediscovery_period_ns", "must be > 0");
  require(params.vacancy_rediscovery_period_ns > 0, "vacancy_rediscovery_period_ns", "must be > 0");
  require(std::isfinite(params.hysteresis_db) && params.hysteresis_db >= 0.0, "hysteresis_db", "must be >= 0");
  require(params.strength_smoothing > 0.0 && params.strength_smoothing <= 1.0, "strength_smoothing",
          "must be in (0, 1]");
  require(params.max_failures >= 1, "max_failures", "must be at least 1");
  require(params.backoff_initial_ns > 0, "backoff_initial_ns", "must be > 0");
  require(params.backoff_max_ns >= params.backoff_initial_ns, "backoff_max_ns", "must be >= backoff_initial_ns");
}

std::int64_t AnchorScheduler::periodNs() const noexcept {
  return static_cast<std::int64_t>(std::llround(1e9 / params_.range_rate_hz));
}

std::int64_t AnchorScheduler::backoffNs(int failures) const noexcept {
  std::int64_t delay = params_.backoff_initial_ns;
  for (int i = 1; i < failures && delay < params_.backoff_max_ns; ++i) delay *= 2;
  return std::min(delay, params_.backoff_max_ns);
}

double AnchorScheduler::strengthFromRangeDb(double range_m) noexcept {
  return -20.0 * std::log10(std::max(range_m, 0.1));
}

std::size_t AnchorScheduler::activeCount() const noexcept {
  return static_cast<std::size_t>(
      std::count_if(anchors_.begin(), anchors_.end(), [](const Anchor& a) { return a.state == State::kActive; }));
}

std::size_t AnchorScheduler::weakestActive() const noexcept {
  std::size_t weakest = anchors_.size();
  for (std::size_t i = 0; i < anchors_.size(); ++i) {
    if (anchors_[i].state != State::kActive) continue;
    if (weakest == anchors_.size() || anchors_[i].strength_db < anchors_[weakest].strength_db) weakest = i;
  }
  return weakest;
}

AnchorScheduler::Pick AnchorScheduler::next(std::int64_t now_ns) const noexcept {
  Pick best;
  for (std::size_t i = 0; i < anchors_.size(); ++i) {
    const Anchor& a = anchors_[i];
    if (a.state == State::kActive && a.next_due_ns < best.at_ns) best = Pick{i, a.next_due_ns, false};
  }
  // Initial sweep: every anchor is polled once as soon as possible.
  for (std::size_t i = 0; i < anchors_.size(); ++i) {
    if (anchors_[i].state == State::kUnknown) {
      if (best.at_ns > now_ns) best = Pick{i, now_ns, true};
      return best;
    }
  }
  // Rediscovery: the next candidate after the cursor, round robin.
  const std::size_t n = anchors_.size();
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = (rediscovery_cursor_ + k) % n;
    if (anchors_[i].state == State::kCandidate) {
      if (next_rediscovery_ns_ < best.at_ns) best = Pick{i, next_rediscovery_ns_, true};
      break;
    }
  }
  return best;
}

void AnchorScheduler::promote(std::size_t index, std::int64_t now_ns) noexcept {
  anchors_[index].state = State::kActive;
  anchors_[index].next_due_ns = now_ns + periodNs();
}

void AnchorScheduler::reportSuccess(std::size_t index, std::int64_t now_ns, double strength_db) noexcept {
  if (index >= anchors_.size()) return;
  Anchor& a = anchors_[index];
  a.failures = 0;
  if (std::isfinite(strength_db)) {
    // Active anchors are smoothed; a candidate's polls are far apart, so its
    // latest value replaces the stale history (it may have come closer).
    const bool smooth = a.has_strength && a.state == State::kActive;
    a.strength_db = smooth ? a.strength_db + params_.strength_smoothing * (strength_db - a.strength_db) : strength_db;
    a.has_strength = true;
  }
  if (a.state == State::kActive) {
    a.next_due_ns += periodNs();
    if (a.next_due_ns < now_ns) a.next_due_ns = now_ns;
    return;
  }
  // A discovery poll answered.
  a.state = State::kCandidate;
  rediscovery_cursor_ = (index + 1) % anchors_.size();
  if (activeCount() < params_.max_active) {
    promote(index, now_ns);
  } else {
    const std::size_t weakest = weakestActive();
    if (weakest < anchors_.size() && a.strength_db > anchors_[weakest].strength_db + params_.hysteresis_db) {
      anchors_[weakest].state = State::kCandidate;
      promote(index, now_ns);
    }
  }
  next_rediscovery_ns_ = now_ns + (activeCount() < params_.max_active ? params_.vacancy_rediscovery_period_ns
                                                                       : params_.rediscovery_period_ns);
}

bool AnchorScheduler::reportFailure(std::size_t index, std::int64_t now_ns) noexcept {
  if (index >= anchors_.size()) return false;
  Anchor& a = anchors_[index];
  ++a.failures;
  if (a.state == State::kActive) {
    if (a.failures < params_.max_failures) {
      a.next_due_ns = now_ns + backoffNs(a.failures);
      return false;
    }
    // Dropped: its old strength no longer says anything; the vacancy makes
    // rediscovery run at the faster rate.
    a.state = State::kCandidate;
    a.has_strength = false;
    a.strength_db = -std::numeric_limits<double>::infinity();
    next_rediscovery_ns_ = std::min(next_rediscovery_ns_, now_ns + params_.vacancy_rediscovery_period_ns);
    rediscovery_cursor_ = (index + 1) % anchors_.size();
    return true;
  }
  a.state = State::kCandidate;
  a.has_strength = false;
  a.strength_db = -std::numeric_limits<double>::infinity();
  rediscovery_cursor_ = (index + 1) % anchors_.size();
  next_rediscovery_ns_ = now_ns + (activeCount() < params_.max_active ? params_.vacancy_rediscovery_period_ns
                                                                       : params_.rediscovery_period_ns);
  return false;
}

}  // namespace rilo::dw3000
