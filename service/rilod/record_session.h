#pragma once
// A recording session without the estimator (`rilo record`): every source
// runs in its own thread and pushes into its own Recorder channel (wait-free;
// the Recorder's writer thread flushes every flush_interval_ns, so a crash
// loses at most that much), until `stop` is set (SIGINT/SIGTERM, --seconds),
// every source ended, or one failed for good. Works on any SampleSource: the
// hardware drivers on the board, sources built on the emulators or a replay
// in tests.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "hal/source.h"
#include "rilod/recorder.h"

namespace rilo {

struct RecordSessionOptions {
  /// Stop every source as soon as one fails fatally (a recording without
  /// the IMU or without ranges is of no use).
  bool stop_on_failure = true;
  /// How often the session checks `stop` and the sources (> 0).
  std::int64_t poll_period_ns = 10'000'000;
  /// Progress callback period (0: none).
  std::int64_t progress_period_ns = 0;
};

/// Per-source tallies (snapshot).
struct SourceTally {
  std::string name;          ///< describe() of the source
  std::uint64_t imu = 0;
  std::uint64_t ranges = 0;
  std::uint64_t tdoa = 0;
  std::uint64_t ultrasonic = 0;
  std::uint64_t faults = 0;
  std::uint64_t fatal_faults = 0;
  std::string last_fault;    ///< text of the last fault (after the session)
  SourceEnd end = SourceEnd::kStopped;
  bool finished = false;
};

struct RecordSessionResult {
  std::vector<SourceTally> sources;
  RecorderCounters recorder;  ///< after close()
  std::string recorder_error; ///< Recorder::error() after close()
  bool recorder_failed = false;
  double seconds = 0.0;       ///< wall time of the session
  bool interrupted = false;   ///< ended by `stop`
  /// 0: clean (stopped or end of data, every sample written); 1: a source
  /// failed or the recording had an I/O error.
  int exitCode() const noexcept;
};

/// Callbacks from the session (any may be empty). on_fault and on_note run
/// on the source's thread (rare path; may log); on_progress on the calling
/// thread.
struct RecordSessionCallbacks {
  std::function<void(const SourceFault&)> on_fault;
  std::function<void(const SourceNote&)> on_note;  ///< a device started or re-initialized, and what it read
  std::function<void(const std::vector<SourceTally>&, const RecorderCounters&)> on_progress;
};

/// Runs `sources` (borrowed; recorder channel i for sources[i], so the
/// recorder needs sources.size() channels) until one of the end conditions,
/// then closes the recorder. Throws std::invalid_argument for a channel count
/// mismatch or bad options.
RecordSessionResult runRecordSession(const std::vector<SampleSource*>& sources, Recorder& recorder,
                                     const std::atomic<bool>& stop, const RecordSessionOptions& options = {},
                                     const RecordSessionCallbacks& callbacks = {});

}  // namespace rilo
