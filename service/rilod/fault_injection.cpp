#include "rilod/fault_injection.h"

#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <utility>
#include <variant>

namespace rilo {

namespace {

std::int64_t secondsToNs(double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); }

std::int64_t sampleTime(const Sample& s) noexcept {
  return std::visit([](const auto& v) { return v.t_ns; }, s);
}

bool matches(FaultStream stream, bool is_imu) noexcept {
  switch (stream) {
    case FaultStream::kAll: return true;
    case FaultStream::kImu: return is_imu;
    case FaultStream::kRanging: return !is_imu;
  }
  return false;
}

std::string formatSeconds(double s) {
  char text[32];
  std::snprintf(text, sizeof text, "%g s", s);
  return text;
}

}  // namespace

void FaultSpec::validate() const {
  auto fail = [](const char* field, const std::string& rule) {
    throw std::invalid_argument(std::string("FaultSpec.") + field + " " + rule);
  };
  if (!(std::isfinite(at_s) && at_s >= 0.0)) fail("at_s", "must be finite and >= 0");
  if (isWindow()) {
    if (!(std::isfinite(duration_s) && duration_s > 0.0)) {
      fail("duration_s", "must be finite and > 0 for " + std::string(toString(kind)));
    }
  } else if (count == 0) {
    fail("count", "must be > 0 for " + std::string(toString(kind)));
  }
}

std::string_view toString(FaultKind kind) {
  switch (kind) {
    case FaultKind::kRangeBlackout: return "range_blackout";
    case FaultKind::kImuGap: return "imu_gap";
    case FaultKind::kDuplicate: return "duplicate";
    case FaultKind::kOutOfOrder: return "out_of_order";
    case FaultKind::kNonFinite: return "non_finite";
    case FaultKind::kImpossible: return "impossible";
    case FaultKind::kFarFuture: return "far_future";
  }
  return "unknown";
}

std::string_view toString(FaultStream stream) {
  switch (stream) {
    case FaultStream::kAll: return "all";
    case FaultStream::kImu: return "imu";
    case FaultStream::kRanging: return "ranging";
  }
  return "unknown";
}

std::string describe(const FaultSpec& fault) {
  std::string text(toString(fault.kind));
  if (fault.isWindow()) {
    text += ' ' + formatSeconds(fault.duration_s);
  } else {
    text += ' ' + std::to_string(fault.count);
    if (fault.stream != FaultStream::kAll) text += ' ' + std::string(toString(fault.stream));
    text += fault.count == 1 ? " sample" : " samples";
  }
  return text + " at " + formatSeconds(fault.at_s);
}

// The sink the wrapped source pushes into. Everything it needs per sample is
// sized in the constructor.
class FaultInjectingSource::Injector final : public SampleSink {
 public:
  Injector(SampleSink& out, const std::vector<FaultSpec>& faults, InjectedFaults& injected)
      : out_(out), faults_(faults), injected_(injected) {
    plan_.reserve(faults.size());
    for (const FaultSpec& f : faults) {
      Active a;
      a.begin_ns = secondsToNs(f.at_s);
      a.end_ns = f.isWindow() ? a.begin_ns + secondsToNs(f.duration_s) : std::numeric_limits<std::int64_t>::max();
      a.remaining = f.count;
      plan_.push_back(a);
    }
  }

  void push(const Sample& sample) noexcept override {
    const std::int64_t t = sampleTime(sample);
    if (!have_t0_) {
      t0_ns_ = t;
      have_t0_ = true;
    }
    const std::int64_t rel_ns = t - t0_ns_;
    const bool is_imu = std::holds_alternative<ImuSample>(sample);

    Sample s = sample;
    bool hold = false, duplicate = false;
    for (std::size_t i = 0; i < faults_.size(); ++i) {
      const FaultSpec& f = faults_[i];
      Active& a = plan_[i];
      if (rel_ns < a.begin_ns || rel_ns >= a.end_ns) continue;
      switch (f.kind) {
        case FaultKind::kRangeBlackout:
          if (!is_imu) return drop();
          break;
        case FaultKind::kImuGap:
          if (is_imu) return drop();
          break;
        case FaultKind::kNonFinite:
          if (matches(f.stream, is_imu) && a.remaining > 0) {
            --a.remaining;
            corrupt(s);
          }
          break;
        case FaultKind::kImpossible:
          if (matches(f.stream, is_imu) && a.remaining > 0) {
            --a.remaining;
            makeImpossible(s);
          }
          break;
        case FaultKind::kFarFuture:
          if (matches(f.stream, is_imu) && a.remaining > 0) {
            --a.remaining;
            ++injected_.far_future;
            std::visit([](auto& v) { v.t_ns += 900'000'000'000'000'000; }, s);
          }
          break;
        case FaultKind::kOutOfOrder:
          // The successor of a held sample is never held itself: it must go out first.
          if (matches(f.stream, is_imu) && a.remaining > 0 && !held_[s.index()].has_value() && !hold) {
            --a.remaining;
            hold = true;
          }
          break;
        case FaultKind::kDuplicate:
          if (matches(f.stream, is_imu) && a.remaining > 0 && !duplicate) {
            --a.remaining;
            duplicate = true;
          }
          break;
      }
    }

    std::optional<Sample>& held = held_[s.index()];
    if (hold) {
      held = s;  // goes out after the next sample of its kind
      return;
    }
    out_.push(s);
    if (duplicate) {
      out_.push(s);
      ++injected_.duplicated;
    }
    if (held.has_value()) {
      out_.push(*held);
      held.reset();
      ++injected_.reordered;
    }
  }

  void fault(const SourceFault& fault) noexcept override { out_.fault(fault); }
  void idle() noexcept override { out_.idle(); }
  void note(const SourceNote& note) noexcept override { out_.note(note); }

  /// Delivers the samples still held back (end of the wrapped source's data).
  void flush() noexcept {
    for (std::optional<Sample>& held : held_) {
      if (!held.has_value()) continue;
      out_.push(*held);
      held.reset();
    }
  }

 private:
  struct Active {
    std::int64_t begin_ns = 0, end_ns = 0;  // relative to the first sample
    std::uint32_t remaining = 0;            // counted kinds
  };

  void drop() noexcept { ++injected_.dropped; }

  void corrupt(Sample& s) noexcept {
    const double bad = injected_.corrupted % 2 == 0 ? std::numeric_limits<double>::quiet_NaN()
                                                    : std::numeric_limits<double>::infinity();
    ++injected_.corrupted;
    if (auto* imu = std::get_if<ImuSample>(&s)) {
      imu->accel_m_s2.x() = bad;
    } else if (auto* range = std::get_if<RangeSample>(&s)) {
      range->range_m = bad;
    } else if (auto* tdoa = std::get_if<TdoaSample>(&s)) {
      tdoa->diff_m = bad;
    } else if (auto* us = std::get_if<UltrasonicSample>(&s)) {
      us->range_m = bad;
    }
  }

  void makeImpossible(Sample& s) noexcept {
    // Ranging alternates between its two impossible values on its own count.
    const bool ranging = !std::holds_alternative<ImuSample>(s);
    const double range = impossible_ranging_ % 2 == 0 ? -5.0 : 1e9;
    ++injected_.impossible;
    if (ranging) ++impossible_ranging_;
    if (auto* imu = std::get_if<ImuSample>(&s)) {
      imu->accel_m_s2.x() = 1e30;
    } else if (auto* r = std::get_if<RangeSample>(&s)) {
      r->range_m = range;
    } else if (auto* tdoa = std::get_if<TdoaSample>(&s)) {
      tdoa->diff_m = 1e9;
    } else if (auto* us = std::get_if<UltrasonicSample>(&s)) {
      us->range_m = range;
    }
  }

  SampleSink& out_;
  const std::vector<FaultSpec>& faults_;
  InjectedFaults& injected_;
  std::vector<Active> plan_;
  bool have_t0_ = false;
  std::int64_t t0_ns_ = 0;
  std::uint64_t impossible_ranging_ = 0;
  std::array<std::optional<Sample>, std::variant_size_v<Sample>> held_{};
};

FaultInjectingSource::FaultInjectingSource(std::unique_ptr<SampleSource> inner, std::vector<FaultSpec> faults)
    : inner_(std::move(inner)), faults_(std::move(faults)) {
  if (!inner_) throw std::invalid_argument("FaultInjectingSource: null source");
  for (const FaultSpec& f : faults_) f.validate();
}

SourceEnd FaultInjectingSource::run(SampleSink& sink, const std::atomic<bool>& stop) {
  injected_ = InjectedFaults{};
  Injector injector(sink, faults_, injected_);
  const SourceEnd end = inner_->run(injector, stop);
  if (end == SourceEnd::kEndOfData) injector.flush();
  return end;
}

std::string FaultInjectingSource::describe() const {
  std::string text = inner_->describe() + " with injected faults: ";
  for (std::size_t i = 0; i < faults_.size(); ++i) text += (i > 0 ? ", " : "") + rilo::describe(faults_[i]);
  if (faults_.empty()) text += "none";
  return text;
}

}  // namespace rilo
