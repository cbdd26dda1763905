#pragma once
// Replay of a recording folder (docs/recording-format.md) through the same
// SampleSource interface as the hardware drivers.
//
// Order. The IMU, range, TDoA and ultrasonic samples are merged by t_ns. At
// equal t_ns the order is: IMU, then range, then TDoA, then ultrasonic (an
// estimator has then integrated the IMU up to t before it sees a measurement
// at t), and within one file the file's row order. The merge is stable and
// deterministic.
//
// Pacing.
//  - kAsFastAsPossible: samples are pushed back to back (offline tools,
//    tests, CI); the output does not depend on the machine.
//  - kRealTime: sample t is pushed when the clock reaches
//        start + (t - t_first) / speed
//    where start is the clock at the beginning of run() and t_first the first
//    sample's time; speed 2 replays twice as fast. A sink slower than the
//    schedule delays samples; nothing is dropped, and late samples go out at
//    once (a burst) until the replay is back on schedule.
//  - shift_to_now (paced only): every pushed t_ns gets + (start - t_first),
//    so the first sample carries the clock's time at start. At speed 1 the
//    samples then look like live ones (t_ns ~ CLOCK_MONOTONIC when pushed).
//    At other speeds the recording's time steps are kept (t_ns advances at
//    the recording's rate, not the clock's): an estimator integrating the IMU
//    must see the true dt, so time is shifted, never scaled.
//  The clock and the sleep are injectable (tests run paced replays on a fake
//  clock without sleeping); by default CLOCK_MONOTONIC and clock_nanosleep
//  with TIMER_ABSTIME.
//
// Loop. With `loop`, the end of the data starts the next pass from the
// beginning instead of returning kEndOfData. Pass k's samples carry
// t_ns + k * (span + step), where span is last - first sample time and step
// the mean IMU period (1 ms without IMU), so time keeps increasing at the
// recording's rate across the seam and a paced replay stays on schedule.
// For soak runs and demos: the tag jumps back to its starting place at each
// seam, which an estimator sees as an inconsistency (and re-initializes).
//
// Stop. `stop` is read before every sample and between sleeps of at most
// max_sleep_ns, so run() returns kStopped within max_sleep_ns (paced) or
// one sample (fast) of stop becoming true.
//
// Errors. The recording is read and checked completely by the constructor:
// a malformed recording throws rilo::RecordingError there, whose message has
// the file, line and column ("range.csv:17: column 'range_m': ..."). So a
// constructed ReplaySource cannot fail during run(). The reader's warnings
// (skipped duplicate rows, a line cut by a crash, unknown columns ...) are
// delivered by run() first, each as a non-fatal SourceFault with device
// "replay:<dir>/<file>".
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "hal/recording/recording.h"
#include "hal/recording/recording_error.h"
#include "hal/source.h"

namespace rilo {

struct ReplayOptions {
  enum class Pacing { kAsFastAsPossible, kRealTime };
  Pacing pacing = Pacing::kAsFastAsPossible;
  double speed = 1.0;          ///< kRealTime: recording seconds per clock second, > 0
  bool shift_to_now = false;   ///< kRealTime: shift t_ns so the first sample is at the start time
  bool loop = false;           ///< at the end, replay again from the start (time keeps increasing)
  bool imu = true;             ///< streams to replay
  bool ranges = true;
  bool tdoa = true;
  bool ultrasonic = true;
  std::int64_t max_sleep_ns = 20'000'000;  ///< longest single sleep (bounds the reaction to stop), > 0
  /// Clock (ns); empty = CLOCK_MONOTONIC.
  std::function<std::int64_t()> now_ns;
  /// Sleeps until the clock reaches the given time (may return early); empty = clock_nanosleep.
  std::function<void(std::int64_t wake_ns)> sleep_until_ns;
};

class ReplaySource final : public SampleSource {
 public:
  /// Reads and checks the recording in `dir`. Throws RecordingError if it is
  /// malformed, std::invalid_argument for bad options.
  explicit ReplaySource(const std::filesystem::path& dir, ReplayOptions options = {});
  /// Replays a recording already in memory (it must be valid: as read by
  /// readRecording). `name` appears in describe() and in fault devices.
  ReplaySource(Recording recording, std::string name, ReplayOptions options = {});

  /// Pushes the samples in order until the end (kEndOfData; never with
  /// `loop` unless there is nothing to replay) or `stop` (kStopped). May be
  /// called again: each call replays from the start.
  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override;
  std::string describe() const override;

  const Recording& recording() const { return recording_; }
  const ReadReport& readReport() const { return report_; }
  /// Number of samples run() pushes (of the selected streams).
  std::size_t sampleCount() const;
  /// The shift added to t_ns by the last run() (0 unless shift_to_now).
  std::int64_t timeShiftNs() const { return shift_ns_; }
  /// Passes begun by the last run() (1 without `loop`; 0 if it pushed nothing).
  std::int64_t passes() const { return passes_; }
  /// Time added to the samples of each further pass with `loop`.
  std::int64_t passPeriodNs() const;

 private:
  void checkOptions() const;
  std::int64_t now() const;
  void sleepUntil(std::int64_t wake_ns) const;

  Recording recording_;
  ReadReport report_;
  std::string name_;
  ReplayOptions options_;
  std::int64_t shift_ns_ = 0;
  std::int64_t passes_ = 0;
};

}  // namespace rilo
