#pragma once
// Recording mode: every raw sample the sources produce is written to a
// recording folder (shared/docs/recording-format.md) as it arrives.
//
// Threads. Each source thread gets its own channel (a SampleSink whose push()
// is one wait-free tryPush into a fixed-capacity SPSC queue: no lock, no
// allocation, no system call); one writer thread drains the channels into a
// RecordingWriter. A full queue drops the sample and counts it; the source
// never waits for the disk.
//
// Durability. The writer hands its buffers to the kernel every
// flush_interval_ns (RecordingWriter's time trigger, also checked while the
// streams are quiet), so a crash of the service loses at most the samples of
// the last flush interval plus those still queued (one poll period); with
// `sync`, each flush is followed by fdatasync and a power cut loses no more
// either. Files on disk are always whole lines.
//
// Bad samples. The writer refuses what a reader would reject (non-finite
// values, time going backwards, unknown anchors, duplicates): such samples are
// counted as rejected and skipped, the recording continues. An I/O error
// (disk full, removed folder) stops recording for good: failed() turns true,
// error() says why, samples are then dropped and counted; the service goes on.
//
// Per stream, samples must reach the recorder in time order (each stream has
// one source: IMU from the IMU thread, ranges from the UWB thread).
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "hal/recording/recording.h"
#include "hal/recording/recording_writer.h"
#include "hal/source.h"
#include "runtime/spsc_queue.h"

namespace rilo {

struct RecorderOptions {
  std::int64_t flush_interval_ns = 200'000'000;  ///< > 0: a crash loses at most this much
  bool sync = false;                             ///< fdatasync after each flush
  std::size_t queue_capacity = 8192;             ///< samples per channel (10 s of IMU at 800 Hz)
  /// The writer thread sleeps this long when every queue is empty (> 0).
  std::int64_t poll_period_ns = 5'000'000;
};

/// What the recording folder describes besides the samples.
struct RecordingSetup {
  RecordingMeta meta;
  std::vector<Anchor> anchors;  ///< written to anchors.csv before any sample
  std::vector<Tag> tags;        ///< empty: one antenna, tag 0 at meta.uwb_lever_arm_m
};

struct RecorderCounters {
  std::uint64_t written = 0;        ///< samples handed to the writer and accepted
  std::uint64_t dropped_full = 0;   ///< push() found the channel's queue full
  std::uint64_t rejected = 0;       ///< refused by the writer (bad or out-of-order sample)
  std::uint64_t dropped_failed = 0; ///< discarded after an I/O error stopped the recording
  std::uint64_t faults = 0;         ///< SourceFaults seen (not recorded: the format has no file for them)
  std::uint64_t flushes = 0;        ///< explicit flush() calls completed
};

class Recorder {
 public:
  /// Creates the recording in `dir` (which must not hold a recording yet),
  /// writes meta.yaml, anchors.csv (and tags.csv) at once, and starts the
  /// writer thread. `channels` is the number of producer threads (>= 1).
  /// Throws std::invalid_argument for bad options or setup, std::system_error
  /// if the folder cannot be written.
  Recorder(std::filesystem::path dir, const RecordingSetup& setup, std::size_t channels,
           RecorderOptions options = {});
  /// close(), swallowing errors.
  ~Recorder();
  Recorder(const Recorder&) = delete;
  Recorder& operator=(const Recorder&) = delete;

  /// The sink of producer thread `index` (< channels). One thread per channel.
  SampleSink& channel(std::size_t index);

  /// Blocks until every sample pushed before the call is written and the
  /// files are flushed (handed to the kernel). Not for the real-time path.
  void flush();
  /// Stops the writer thread after draining the queues, then closes the
  /// files. Producers must have stopped pushing. Idempotent.
  void close();

  RecorderCounters counters() const noexcept;
  bool failed() const noexcept { return failed_.load(std::memory_order_acquire); }
  /// The I/O error that stopped the recording, or the first rejection reason
  /// if none; empty if neither happened.
  std::string error() const;
  const std::filesystem::path& dir() const noexcept { return dir_; }
  /// The writer thread (for its real-time settings: name, CPU, priority).
  std::thread& thread() noexcept { return thread_; }

 private:
  class Channel final : public SampleSink {
   public:
    explicit Channel(std::size_t capacity) : queue(capacity) {}
    void push(const Sample& sample) noexcept override;
    void fault(const SourceFault& fault) noexcept override;

    SpscQueue<Sample> queue;
    std::atomic<std::uint64_t> dropped_full{0};
    std::atomic<std::uint64_t> faults{0};
  };

  void run();
  /// Pops and writes what the queues hold now; returns the number popped.
  std::size_t drainOnce();
  void write(const Sample& sample);
  void fail(const std::string& what);

  std::filesystem::path dir_;
  RecorderOptions options_;
  std::unique_ptr<RecordingWriter> writer_;  // owned by the writer thread once it runs
  std::vector<std::unique_ptr<Channel>> channels_;

  std::atomic<std::uint64_t> written_{0}, rejected_{0}, dropped_failed_{0}, flushes_{0};
  std::atomic<bool> failed_{false};

  mutable std::mutex mutex_;  // control only (flush, close, error text): never taken by producers
  std::condition_variable wake_, flushed_;
  bool stop_requested_ = false;
  std::uint64_t flush_requested_ = 0;
  std::uint64_t flush_done_ = 0;
  std::string error_;
  bool closed_ = false;
  std::thread thread_;
};

/// Forwards every sample and fault to two sinks (e.g. the estimator's queue
/// and a recorder channel), first `a` then `b`.
class TeeSink final : public SampleSink {
 public:
  TeeSink(SampleSink& a, SampleSink& b) : a_(a), b_(b) {}
  void push(const Sample& sample) noexcept override {
    a_.push(sample);
    b_.push(sample);
  }
  void idle() noexcept override {
    a_.idle();
    b_.idle();
  }
  void fault(const SourceFault& fault) noexcept override {
    a_.fault(fault);
    b_.fault(fault);
  }
  void note(const SourceNote& note) noexcept override {
    a_.note(note);
    b_.note(note);
  }

 private:
  SampleSink& a_;
  SampleSink& b_;
};

/// Creates and returns a new, empty folder `<base>/rilod-YYYYmmdd-HHMMSS`
/// (UTC time of `now`), with "-2", "-3"... appended if that name is taken
/// (creation is atomic, so two services never share a folder). Creates `base`
/// if needed. Throws std::system_error naming the path on failure.
std::filesystem::path newRecordingDirectory(const std::filesystem::path& base,
                                            std::chrono::system_clock::time_point now = std::chrono::system_clock::now());

}  // namespace rilo
