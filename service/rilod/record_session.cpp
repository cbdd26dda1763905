#include "rilod/record_session.h"

#include <chrono>
#include <exception>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <variant>

namespace rilo {
namespace {

/// Forwards to a recorder channel and counts (relaxed atomics: read for
/// progress from another thread; exact after the thread is joined).
class TallySink final : public SampleSink {
 public:
  TallySink(SampleSink& channel, const RecordSessionCallbacks& callbacks)
      : channel_(channel), on_fault_(callbacks.on_fault), on_note_(callbacks.on_note) {}

  void push(const Sample& sample) noexcept override {
    channel_.push(sample);
    switch (sample.index()) {
      case 0: imu.fetch_add(1, std::memory_order_relaxed); break;
      case 1: ranges.fetch_add(1, std::memory_order_relaxed); break;
      case 2: tdoa.fetch_add(1, std::memory_order_relaxed); break;
      default: ultrasonic.fetch_add(1, std::memory_order_relaxed); break;
    }
  }

  void fault(const SourceFault& f) noexcept override {
    channel_.fault(f);
    faults.fetch_add(1, std::memory_order_relaxed);
    if (f.fatal) fatal_faults.fetch_add(1, std::memory_order_relaxed);
    try {
      {
        const std::lock_guard<std::mutex> lock(mutex_);
        last_fault_ = f.device + ": " + f.what;
      }
      if (on_fault_) on_fault_(f);
    } catch (...) {  // a logging failure must not end the source
    }
  }

  void note(const SourceNote& n) noexcept override {
    channel_.note(n);
    try {
      if (on_note_) on_note_(n);
    } catch (...) {  // a logging failure must not end the source
    }
  }

  std::string lastFault() const {
    const std::lock_guard<std::mutex> lock(mutex_);
    return last_fault_;
  }

  std::atomic<std::uint64_t> imu{0}, ranges{0}, tdoa{0}, ultrasonic{0}, faults{0}, fatal_faults{0};
  std::atomic<bool> finished{false};
  SourceEnd end = SourceEnd::kStopped;  // written by the source thread before `finished`

 private:
  SampleSink& channel_;
  const std::function<void(const SourceFault&)>& on_fault_;
  const std::function<void(const SourceNote&)>& on_note_;
  mutable std::mutex mutex_;  // the fault text only (rare path)
  std::string last_fault_;
};

SourceTally snapshot(const SampleSource& source, const TallySink& sink) {
  SourceTally t;
  t.name = source.describe();
  t.imu = sink.imu.load(std::memory_order_relaxed);
  t.ranges = sink.ranges.load(std::memory_order_relaxed);
  t.tdoa = sink.tdoa.load(std::memory_order_relaxed);
  t.ultrasonic = sink.ultrasonic.load(std::memory_order_relaxed);
  t.faults = sink.faults.load(std::memory_order_relaxed);
  t.fatal_faults = sink.fatal_faults.load(std::memory_order_relaxed);
  t.finished = sink.finished.load(std::memory_order_acquire);
  if (t.finished) t.end = sink.end;
  return t;
}

}  // namespace

int RecordSessionResult::exitCode() const noexcept {
  if (recorder_failed) return 1;
  for (const SourceTally& s : sources) {
    if (s.end == SourceEnd::kFailed) return 1;
  }
  return 0;
}

RecordSessionResult runRecordSession(const std::vector<SampleSource*>& sources, Recorder& recorder,
                                     const std::atomic<bool>& stop, const RecordSessionOptions& options,
                                     const RecordSessionCallbacks& callbacks) {
  if (sources.empty()) throw std::invalid_argument("runRecordSession: sources must not be empty");
  for (const SampleSource* s : sources) {
    if (s == nullptr) throw std::invalid_argument("runRecordSession: sources must not contain null");
  }
  if (options.poll_period_ns <= 0) throw std::invalid_argument("RecordSessionOptions: poll_period_ns must be > 0");
  if (options.progress_period_ns < 0) {
    throw std::invalid_argument("RecordSessionOptions: progress_period_ns must be >= 0");
  }
  std::vector<std::unique_ptr<TallySink>> sinks;
  for (std::size_t i = 0; i < sources.size(); ++i) {
    SampleSink* channel = nullptr;
    try {
      channel = &recorder.channel(i);
    } catch (const std::out_of_range&) {
      throw std::invalid_argument("runRecordSession: the recorder has fewer channels than the " +
                                  std::to_string(sources.size()) + " sources");
    }
    sinks.push_back(std::make_unique<TallySink>(*channel, callbacks));
  }

  const auto t0 = std::chrono::steady_clock::now();
  std::atomic<bool> stop_sources{false};
  std::vector<std::thread> threads;
  threads.reserve(sources.size());
  for (std::size_t i = 0; i < sources.size(); ++i) {
    threads.emplace_back([&, i] {
      TallySink& sink = *sinks[i];
      SourceEnd end = SourceEnd::kFailed;
      try {
        end = sources[i]->run(sink, stop_sources);
      } catch (const std::exception& e) {
        sink.fault(SourceFault{0, sources[i]->describe(), std::string("source ended by an exception: ") + e.what(), true});
      } catch (...) {
        sink.fault(SourceFault{0, sources[i]->describe(), "source ended by an unknown exception", true});
      }
      sink.end = end;
      sink.finished.store(true, std::memory_order_release);
    });
  }

  RecordSessionResult result;
  const auto poll = std::chrono::nanoseconds(options.poll_period_ns);
  auto next_progress = t0 + std::chrono::nanoseconds(options.progress_period_ns);
  for (;;) {
    bool all_finished = true;
    bool failed = false;
    for (const auto& sink : sinks) {
      const bool finished = sink->finished.load(std::memory_order_acquire);
      all_finished = all_finished && finished;
      failed = failed || (finished && sink->end == SourceEnd::kFailed);
    }
    if (all_finished) break;
    if (stop.load(std::memory_order_relaxed)) {
      result.interrupted = true;
      break;
    }
    if (failed && options.stop_on_failure) break;
    const auto now = std::chrono::steady_clock::now();
    if (options.progress_period_ns > 0 && now >= next_progress && callbacks.on_progress) {
      std::vector<SourceTally> tallies;
      for (std::size_t i = 0; i < sources.size(); ++i) tallies.push_back(snapshot(*sources[i], *sinks[i]));
      callbacks.on_progress(tallies, recorder.counters());
      next_progress = now + std::chrono::nanoseconds(options.progress_period_ns);
    }
    std::this_thread::sleep_for(poll);
  }
  stop_sources.store(true, std::memory_order_relaxed);
  for (std::thread& t : threads) t.join();
  recorder.close();

  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (std::size_t i = 0; i < sources.size(); ++i) {
    SourceTally t = snapshot(*sources[i], *sinks[i]);
    t.last_fault = sinks[i]->lastFault();
    result.sources.push_back(std::move(t));
  }
  result.recorder = recorder.counters();
  result.recorder_failed = recorder.failed();
  result.recorder_error = recorder.error();
  return result;
}

}  // namespace rilo
