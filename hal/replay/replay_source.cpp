#include "hal/replay/replay_source.h"

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include "hal/bus/clock.h"
#include "hal/recording/recording_reader.h"

namespace rilo {
namespace {

void monotonicSleepUntil(std::int64_t wake_ns) {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(wake_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(wake_ns % 1'000'000'000);
  // EINTR: return early; the caller re-checks the clock and the stop flag.
  clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
}

/// Stream kinds in their order at equal t_ns.
enum Stream : int { kImu = 0, kRange = 1, kTdoa = 2, kUltrasonic = 3, kStreams = 4 };

}  // namespace

ReplaySource::ReplaySource(const std::filesystem::path& dir, ReplayOptions options)
    : name_(dir.string()), options_(std::move(options)) {
  checkOptions();
  recording_ = readRecording(dir, &report_);  // RecordingError: file, line, column
}

ReplaySource::ReplaySource(Recording recording, std::string name, ReplayOptions options)
    : recording_(std::move(recording)), name_(std::move(name)), options_(std::move(options)) {
  checkOptions();
}

void ReplaySource::checkOptions() const {
  if (!(std::isfinite(options_.speed) && options_.speed > 0.0)) {
    throw std::invalid_argument("ReplayOptions.speed must be finite and > 0");
  }
  if (options_.max_sleep_ns <= 0) throw std::invalid_argument("ReplayOptions.max_sleep_ns must be > 0");
}

std::int64_t ReplaySource::now() const { return options_.now_ns ? options_.now_ns() : hal::monotonicNowNs(); }

void ReplaySource::sleepUntil(std::int64_t wake_ns) const {
  if (options_.sleep_until_ns) {
    options_.sleep_until_ns(wake_ns);
  } else {
    monotonicSleepUntil(wake_ns);
  }
}

std::size_t ReplaySource::sampleCount() const {
  return (options_.imu ? recording_.imu.size() : 0) + (options_.ranges ? recording_.ranges.size() : 0) +
         (options_.tdoa ? recording_.tdoa.size() : 0) + (options_.ultrasonic ? recording_.ultrasonic.size() : 0);
}

std::int64_t ReplaySource::passPeriodNs() const {
  const Recording& r = recording_;
  std::int64_t first = std::numeric_limits<std::int64_t>::max();
  std::int64_t last = std::numeric_limits<std::int64_t>::min();
  auto span = [&](const auto& rows, bool selected) {
    if (!selected || rows.empty()) return;
    first = std::min(first, rows.front().t_ns);  // each file is in time order (reader)
    last = std::max(last, rows.back().t_ns);
  };
  span(r.imu, options_.imu);
  span(r.ranges, options_.ranges);
  span(r.tdoa, options_.tdoa);
  span(r.ultrasonic, options_.ultrasonic);
  if (first > last) return 0;
  std::int64_t step = 1'000'000;
  if (options_.imu && r.imu.size() >= 2) {
    const auto intervals = static_cast<std::int64_t>(r.imu.size() - 1);
    step = std::max<std::int64_t>(1, (r.imu.back().t_ns - r.imu.front().t_ns) / intervals);
  }
  return last - first + step;
}

std::string ReplaySource::describe() const {
  std::string d = "replay " + name_;
  if (options_.pacing == ReplayOptions::Pacing::kAsFastAsPossible) {
    return d + (options_.loop ? " (as fast as possible, looped)" : " (as fast as possible)");
  }
  char speed[32];
  std::snprintf(speed, sizeof(speed), "%g", options_.speed);
  return d + " (paced x" + speed + (options_.shift_to_now ? ", time shifted to now" : "") + (options_.loop ? ", looped)" : ")");
}

SourceEnd ReplaySource::run(SampleSink& sink, const std::atomic<bool>& stop) {
  for (const ReadWarning& w : report_.warnings) {
    SourceFault f;
    f.device = "replay";  // the message names the file and line (it printed the path twice)
    f.what = w.message;
    f.fatal = false;
    sink.fault(f);
  }

  const Recording& r = recording_;
  const std::size_t sizes[kStreams] = {options_.imu ? r.imu.size() : 0, options_.ranges ? r.ranges.size() : 0,
                                       options_.tdoa ? r.tdoa.size() : 0,
                                       options_.ultrasonic ? r.ultrasonic.size() : 0};
  std::size_t next[kStreams] = {0, 0, 0, 0};
  auto timeOf = [&](int s, std::size_t i) -> std::int64_t {
    switch (s) {
      case kImu: return r.imu[i].t_ns;
      case kRange: return r.ranges[i].t_ns;
      case kTdoa: return r.tdoa[i].t_ns;
      default: return r.ultrasonic[i].t_ns;
    }
  };
  // The stream with the earliest next sample; ties go to the lower stream kind.
  auto pick = [&]() -> int {
    int best = -1;
    std::int64_t best_t = std::numeric_limits<std::int64_t>::max();
    for (int s = 0; s < kStreams; ++s) {
      if (next[s] >= sizes[s]) continue;
      const std::int64_t t = timeOf(s, next[s]);
      if (best < 0 || t < best_t) {
        best = s;
        best_t = t;
      }
    }
    return best;
  };

  const bool paced = options_.pacing == ReplayOptions::Pacing::kRealTime;
  const int first = pick();
  const std::int64_t t_first = first >= 0 ? timeOf(first, 0) : 0;
  const std::int64_t start = paced ? now() : 0;
  const std::int64_t pass_period = options_.loop ? passPeriodNs() : 0;
  shift_ns_ = paced && options_.shift_to_now ? start - t_first : 0;
  passes_ = first >= 0 ? 1 : 0;
  std::int64_t pass_offset = 0;  // pass k: k * pass_period

  for (;;) {
    if (stop.load(std::memory_order_relaxed)) return SourceEnd::kStopped;
    int s = pick();
    if (s < 0) {
      if (!options_.loop || first < 0) return SourceEnd::kEndOfData;
      for (std::size_t& n : next) n = 0;
      pass_offset += pass_period;
      ++passes_;
      s = pick();
    }
    const std::size_t i = next[s]++;
    const std::int64_t t = timeOf(s, i) + pass_offset;
    if (paced) {
      const double offset_ns = static_cast<double>(t - t_first) / options_.speed;
      const std::int64_t due = start + static_cast<std::int64_t>(std::llround(offset_ns));
      for (std::int64_t clock = now(); clock < due; clock = now()) {
        if (stop.load(std::memory_order_relaxed)) return SourceEnd::kStopped;
        sleepUntil(std::min(due, clock + options_.max_sleep_ns));
        sink.idle();
      }
      if (stop.load(std::memory_order_relaxed)) return SourceEnd::kStopped;
    }
    const std::int64_t shift = shift_ns_ + pass_offset;
    switch (s) {
      case kImu: {
        ImuSample m = r.imu[i];
        m.t_ns += shift;
        sink.push(Sample{m});
        break;
      }
      case kRange: {
        RangeSample m = r.ranges[i];
        m.t_ns += shift;
        sink.push(Sample{m});
        break;
      }
      case kTdoa: {
        TdoaSample m = r.tdoa[i];
        m.t_ns += shift;
        sink.push(Sample{m});
        break;
      }
      default: {
        UltrasonicSample m = r.ultrasonic[i];
        m.t_ns += shift;
        sink.push(Sample{m});
        break;
      }
    }
  }
}

}  // namespace rilo
