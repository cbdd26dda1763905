#include "rilod/recorder.h"

#include <time.h>

#include <algorithm>
#include <cerrno>
#include <ctime>
#include <stdexcept>
#include <system_error>
#include <type_traits>
#include <variant>

namespace rilo {

namespace {

RecordingWriterOptions writerOptions(const RecorderOptions& o) {
  RecordingWriterOptions w;
  w.flush_every_records = 0;  // time trigger only (plus the writer's buffer-size bound)
  w.flush_interval_ms = std::max<std::int64_t>(1, o.flush_interval_ns / 1'000'000);
  w.sync = o.sync;
  w.overwrite = false;  // never replace a recording
  return w;
}

}  // namespace

// --- Channel (producer side) ----------------------------------------------------

void Recorder::Channel::push(const Sample& sample) noexcept {
  if (!queue.tryPush(sample)) dropped_full.fetch_add(1, std::memory_order_relaxed);
}

void Recorder::Channel::fault(const SourceFault& /*fault*/) noexcept {
  faults.fetch_add(1, std::memory_order_relaxed);
}

// --- Recorder ---------------------------------------------------------------------

Recorder::Recorder(std::filesystem::path dir, const RecordingSetup& setup, std::size_t channels,
                   RecorderOptions options)
    : dir_(std::move(dir)), options_(options) {
  if (channels == 0) throw std::invalid_argument("Recorder: channels must be >= 1");
  if (options_.flush_interval_ns <= 0) throw std::invalid_argument("Recorder: flush_interval_ns must be > 0");
  if (options_.poll_period_ns <= 0) throw std::invalid_argument("Recorder: poll_period_ns must be > 0");
  if (options_.queue_capacity == 0) throw std::invalid_argument("Recorder: queue_capacity must be >= 1");
  writer_ = std::make_unique<RecordingWriter>(dir_, writerOptions(options_));
  writer_->writeMeta(setup.meta);
  writer_->writeAnchors(setup.anchors);
  if (!setup.tags.empty()) writer_->writeTags(setup.tags);
  channels_.reserve(channels);
  for (std::size_t i = 0; i < channels; ++i) channels_.push_back(std::make_unique<Channel>(options_.queue_capacity));
  thread_ = std::thread([this] { run(); });
}

Recorder::~Recorder() {
  try {
    close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; close() reports errors
  }
}

SampleSink& Recorder::channel(std::size_t index) {
  if (index >= channels_.size()) {
    throw std::out_of_range("Recorder: channel " + std::to_string(index) + " of " + std::to_string(channels_.size()));
  }
  return *channels_[index];
}

void Recorder::fail(const std::string& what) {
  failed_.store(true, std::memory_order_release);
  std::lock_guard<std::mutex> lock(mutex_);
  error_ = "recording " + dir_.string() + " stopped: " + what;
}

void Recorder::write(const Sample& sample) {
  if (failed_.load(std::memory_order_relaxed)) {
    dropped_failed_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  try {
    std::visit([this](const auto& s) { writer_->write(s); }, sample);
    written_.fetch_add(1, std::memory_order_relaxed);
  } catch (const std::logic_error& e) {  // std::invalid_argument: a sample the format refuses
    if (rejected_.fetch_add(1, std::memory_order_relaxed) == 0) {
      std::lock_guard<std::mutex> lock(mutex_);
      if (error_.empty()) error_ = std::string("first rejected sample: ") + e.what();
    }
  } catch (const std::exception& e) {  // I/O: std::system_error
    dropped_failed_.fetch_add(1, std::memory_order_relaxed);
    fail(e.what());
  }
}

std::size_t Recorder::drainOnce() {
  std::size_t popped = 0;
  Sample sample;
  for (auto& channel : channels_) {
    // At most one queue's worth per channel per pass, so a busy channel
    // cannot starve the others or the flush checks.
    for (std::size_t i = 0; i < channel->queue.capacity() && channel->queue.tryPop(sample); ++i) {
      write(sample);
      ++popped;
    }
  }
  return popped;
}

void Recorder::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    const bool stop = stop_requested_;
    const std::uint64_t flush_ticket = flush_requested_;
    lock.unlock();

    std::size_t popped = 0;
    for (std::size_t n = drainOnce(); n > 0; n = drainOnce()) {
      popped += n;
      if (!stop && flush_ticket == flush_done_) break;  // periodic pass: one batch, then check the time trigger
    }
    if (!failed_.load(std::memory_order_relaxed)) {
      try {
        if (stop || flush_ticket != flush_done_) {
          writer_->flush();
        } else {
          writer_->flushIfDue();
        }
      } catch (const std::exception& e) {
        fail(e.what());
      }
    }

    lock.lock();
    if (flush_ticket != flush_done_) {
      flush_done_ = flush_ticket;
      flushed_.notify_all();
    }
    if (stop) break;
    if (popped == 0) {
      wake_.wait_for(lock, std::chrono::nanoseconds(options_.poll_period_ns),
                     [&] { return stop_requested_ || flush_requested_ != flush_ticket; });
    }
  }
  flush_done_ = flush_requested_;  // nothing waits for a thread that has ended
  flushed_.notify_all();
}

void Recorder::flush() {
  std::unique_lock<std::mutex> lock(mutex_);
  if (closed_ || stop_requested_) return;
  const std::uint64_t ticket = ++flush_requested_;
  wake_.notify_all();
  flushed_.wait(lock, [&] { return flush_done_ >= ticket; });
  flushes_.fetch_add(1, std::memory_order_relaxed);
}

void Recorder::close() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (closed_) return;
    closed_ = true;
    stop_requested_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
  // The writer thread has ended: the writer is ours again.
  if (!failed_.load(std::memory_order_acquire)) {
    try {
      writer_->close();
    } catch (const std::exception& e) {
      fail(e.what());
      throw;
    }
  }
}

RecorderCounters Recorder::counters() const noexcept {
  RecorderCounters c;
  c.written = written_.load(std::memory_order_relaxed);
  c.rejected = rejected_.load(std::memory_order_relaxed);
  c.dropped_failed = dropped_failed_.load(std::memory_order_relaxed);
  c.flushes = flushes_.load(std::memory_order_relaxed);
  for (const auto& channel : channels_) {
    c.dropped_full += channel->dropped_full.load(std::memory_order_relaxed);
    c.faults += channel->faults.load(std::memory_order_relaxed);
  }
  return c;
}

std::string Recorder::error() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return error_;
}

std::filesystem::path newRecordingDirectory(const std::filesystem::path& base,
                                            std::chrono::system_clock::time_point now) {
  std::filesystem::create_directories(base);  // throws std::filesystem::filesystem_error (a system_error)
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  std::tm utc{};
  gmtime_r(&t, &utc);
  char stamp[32];
  const std::size_t n = std::strftime(stamp, sizeof(stamp), "%Y%m%d-%H%M%S", &utc);
  const std::string name = "rilod-" + std::string(stamp, n);
  for (int suffix = 1; suffix < 1000; ++suffix) {
    const std::filesystem::path candidate = base / (suffix == 1 ? name : name + "-" + std::to_string(suffix));
    if (std::filesystem::create_directory(candidate)) return candidate;  // false: it exists, try the next
  }
  throw std::system_error(std::make_error_code(std::errc::file_exists),
                          "newRecordingDirectory: no free name for " + (base / name).string());
}

}  // namespace rilo
