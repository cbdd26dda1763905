#include "hal/bmi263/bmi263_source.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

namespace rilo::bmi263 {
namespace {

std::int64_t floorDiv(std::int64_t a, std::int64_t b) noexcept {
  const std::int64_t q = a / b;
  return (a % b != 0 && ((a < 0) != (b < 0))) ? q - 1 : q;
}

std::int64_t ticksToNs(std::int64_t ticks) noexcept {
  return static_cast<std::int64_t>(std::llround(static_cast<double>(ticks) * kSensorTimeTickNs));
}

std::string msText(std::int64_t ns) { return std::to_string(ns / 1'000'000) + " ms"; }

}  // namespace

Bmi263Source::Bmi263Source(hal::I2cDevice& i2c, hal::InterruptLine& irq, hal::Clock& clock, Bmi263Config config)
    : i2c_(i2c),
      irq_(irq),
      clock_(clock),
      config_((config.validate(), std::move(config))),
      driver_(i2c_, clock_, config_),
      fit_(config_.time_fit),
      fifo_parser_(config_.fifo_read_max_bytes / fifo::kAccGyrFrameBytes + 1),
      fifo_buffer_(config_.fifo_read_max_bytes),
      period_ticks_(periodTicks(config_.odr)) {
  counters_.temperature_degc.store(std::numeric_limits<double>::quiet_NaN());
}

std::string Bmi263Source::describe() const {
  return "bmi263 " + i2c_.path() + " irq " + irq_.path() + " (" + toString(config_.odr) + ", " +
         toString(config_.interrupt_mode) + ")";
}

Bmi263Counters Bmi263Source::counters() const noexcept {
  constexpr auto relaxed = std::memory_order_relaxed;
  Bmi263Counters c;
  c.samples = counters_.samples.load(relaxed);
  c.missed_samples = counters_.missed_samples.load(relaxed);
  c.duplicate_reads = counters_.duplicate_reads.load(relaxed);
  c.sensortime_backwards = counters_.sensortime_backwards.load(relaxed);
  c.i2c_retries = driver_.retries();
  c.i2c_failures = driver_.failures();
  c.irq_timeouts = counters_.irq_timeouts.load(relaxed);
  c.irq_errors = counters_.irq_errors.load(relaxed);
  c.stuck_irq = counters_.stuck_irq.load(relaxed);
  c.fifo_overflows = counters_.fifo_overflows.load(relaxed);
  c.fifo_frames_lost = counters_.fifo_frames_lost.load(relaxed);
  c.fifo_parse_errors = counters_.fifo_parse_errors.load(relaxed);
  c.unpaired_edges = counters_.unpaired_edges.load(relaxed);
  c.time_fit_rejections = counters_.time_fit_rejections.load(relaxed);
  c.time_fit_resets = counters_.time_fit_resets.load(relaxed);
  c.bring_ups = counters_.bring_ups.load(relaxed);
  c.bring_up_failures = counters_.bring_up_failures.load(relaxed);
  c.recoveries = counters_.recoveries.load(relaxed);
  c.temperature_reads = counters_.temperature_reads.load(relaxed);
  c.faults_reported = counters_.faults_reported.load(relaxed);
  c.temperature_degc = counters_.temperature_degc.load(relaxed);
  c.oscillator_ppm = counters_.oscillator_ppm.load(relaxed);
  return c;
}

void Bmi263Source::report(const std::string& device, const std::string& what, bool fatal) {
  counters_.faults_reported.fetch_add(1, std::memory_order_relaxed);
  SourceFault fault;
  fault.t_ns = clock_.nowNs();
  fault.device = device;
  fault.what = what;
  fault.fatal = fatal;
  sink_->fault(fault);
}

void Bmi263Source::resetTiming() noexcept {
  fit_.reset();
  unwrapper_.reset();
  has_last_tick_ = false;
  fifo_drained_ = true;  // bring-up flushes the FIFO
}

// ---------------------------------------------------------------------------
// Life cycle

void Bmi263Source::noteStartUp(const BringUpResult& result, bool at_startup) noexcept {
  // What the start-up read and applied, for the log. Only a note: a failure
  // to build it must not fail the start-up.
  try {
    char ids[64];
    std::snprintf(ids, sizeof ids, "chip id 0x%02X, INTERNAL_STATUS 0x%02X", static_cast<unsigned>(result.chip_id),
                  static_cast<unsigned>(result.internal_status));
    const std::string cross_axis = result.gyro_cross_axis
                                       ? "corrected (GYR_CAS " + std::to_string(result.gyro_cas) + ")"
                                       : std::string("not corrected");
    sink_->note(SourceNote{clock_.nowNs(), i2c_.path(),
                           std::string(at_startup ? "started: " : "re-initialized: ") + ids + ", config blob '" +
                               config_.config_blob_path + "' loaded, gyro cross-axis " + cross_axis});
  } catch (...) {
  }
}

bool Bmi263Source::startDevice(const std::atomic<bool>& stop, bool at_startup) {
  const int attempts = config_.bring_up_attempts;
  for (int attempt = 1; attempt <= attempts; ++attempt) {
    if (stop.load(std::memory_order_relaxed)) return false;
    const BringUpResult result = driver_.bringUp();
    if (result.ok) {
      counters_.bring_ups.fetch_add(1, std::memory_order_relaxed);
      noteStartUp(result, at_startup);
      resetTiming();
      timeouts_in_row_ = 0;
      read_failures_in_row_ = 0;
      next_temperature_ns_ = clock_.nowNs();
      discardStaleEdges();
      return true;
    }
    counters_.bring_up_failures.fetch_add(1, std::memory_order_relaxed);
    if (result.permanent) {
      report(i2c_.path(), result.error, true);
      return false;
    }
    if (attempt < attempts) {
      report(i2c_.path(), "bring-up attempt " + std::to_string(attempt) + " of " + std::to_string(attempts) +
                              " failed: " + result.error);
    } else {
      report(i2c_.path(), "bring-up failed " + std::to_string(attempts) + " times, giving up: " + result.error,
             true);
    }
  }
  return false;
}

void Bmi263Source::discardStaleEdges() {
  // Edges queued during the bring-up (the part samples during the start-up
  // wait) belong to samples nobody will read: drop them, so the loop starts
  // on a fresh edge. An edge stamped after the bring-up is kept.
  const std::int64_t ready_ns = clock_.nowNs();
  has_pending_edge_ = false;
  for (int i = 0; i < 64; ++i) {
    hal::EdgeEvent edge;
    std::error_code ignored;
    if (irq_.waitEdge(std::chrono::nanoseconds(0), edge, ignored) != hal::WaitResult::kEdge) return;
    if (edge.t_ns >= ready_ns) {
      pending_edge_ = edge;
      has_pending_edge_ = true;
      return;
    }
  }
}

SourceEnd Bmi263Source::run(SampleSink& sink, const std::atomic<bool>& stop) {
  sink_ = &sink;
  if (!startDevice(stop, true)) return stop.load() ? SourceEnd::kStopped : SourceEnd::kFailed;
  const bool fifo_mode = config_.interrupt_mode == InterruptMode::kFifoWatermark;
  while (!stop.load(std::memory_order_relaxed)) {
    hal::EdgeEvent edge;
    std::error_code error;
    Step step = Step::kContinue;
    hal::WaitResult wait = hal::WaitResult::kEdge;
    if (has_pending_edge_) {
      edge = pending_edge_;
      has_pending_edge_ = false;
    } else {
      wait = irq_.waitEdge(std::chrono::nanoseconds(config_.irq_timeout_ns), edge, error);
    }
    switch (wait) {
      case hal::WaitResult::kEdge:
        timeouts_in_row_ = 0;
        irq_errors_in_row_ = 0;
        step = fifo_mode ? serviceFifo(&edge) : serviceDataReady(&edge);
        break;
      case hal::WaitResult::kTimeout: step = onTimeout(); break;
      case hal::WaitResult::kError: step = onIrqError(error); break;
    }
    if (step == Step::kFatal) return SourceEnd::kFailed;
    sink.idle();  // the loop went round (the watchdog watches this thread too)
    if (step == Step::kRestart) {
      counters_.recoveries.fetch_add(1, std::memory_order_relaxed);
      if (!startDevice(stop, false)) return stop.load() ? SourceEnd::kStopped : SourceEnd::kFailed;
    }
  }
  return SourceEnd::kStopped;
}

// ---------------------------------------------------------------------------
// Faults

Bmi263Source::Step Bmi263Source::onReadFailure() {
  ++read_failures_in_row_;
  report(i2c_.path(), driver_.lastBusError() + "; sample(s) lost");
  if (read_failures_in_row_ >= config_.max_consecutive_read_failures) {
    report(i2c_.path(), std::to_string(read_failures_in_row_) + " reads failed in a row: re-initialising the BMI263");
    return Step::kRestart;
  }
  return Step::kContinue;
}

Bmi263Source::Step Bmi263Source::onTimeout() {
  counters_.irq_timeouts.fetch_add(1, std::memory_order_relaxed);
  ++timeouts_in_row_;
  bool high = false;
  const bool stuck = !irq_.readLevel(high) && high;
  report(irq_.path(), "no interrupt for " + msText(config_.irq_timeout_ns) +
                          (stuck ? " and the line is high: servicing the device without an edge" : ""));
  if (stuck) {
    // A missed edge with the line still asserted (FIFO above the watermark):
    // service the device so the line drops and edges resume.
    counters_.stuck_irq.fetch_add(1, std::memory_order_relaxed);
    const Step step = config_.interrupt_mode == InterruptMode::kFifoWatermark ? serviceFifo(nullptr)
                                                                                : serviceDataReady(nullptr);
    if (step != Step::kContinue) return step;
  }
  if (timeouts_in_row_ >= config_.max_consecutive_irq_timeouts) {
    report(irq_.path(), std::to_string(timeouts_in_row_) + " interrupt timeouts in a row: re-initialising the BMI263");
    return Step::kRestart;
  }
  return Step::kContinue;
}

Bmi263Source::Step Bmi263Source::onIrqError(const std::error_code& error) {
  counters_.irq_errors.fetch_add(1, std::memory_order_relaxed);
  ++irq_errors_in_row_;
  const std::string text = "waiting for an interrupt failed: " + error.message() + " (errno " +
                           std::to_string(error.value()) + ")";
  if (irq_errors_in_row_ >= config_.max_consecutive_irq_errors) {
    report(irq_.path(), text + "; " + std::to_string(irq_errors_in_row_) + " in a row, giving up", true);
    return Step::kFatal;
  }
  report(irq_.path(), text);
  clock_.sleepForNs(config_.irq_error_backoff_ns);
  return Step::kContinue;
}

// ---------------------------------------------------------------------------
// Data path

bool Bmi263Source::acceptTick(std::int64_t tick) {
  if (!has_last_tick_) {
    has_last_tick_ = true;
    last_tick_ = tick;
    return true;
  }
  const std::int64_t step = tick - last_tick_;
  if (step == 0) {
    counters_.duplicate_reads.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  if (step < 0) {
    // The part restarted its counter behind our back (brown-out, reset):
    // drop this sample and start the time keeping over.
    counters_.sensortime_backwards.fetch_add(1, std::memory_order_relaxed);
    report(i2c_.path(), "SENSORTIME went back by " + std::to_string(-step) +
                            " ticks: device reset? time fit restarted");
    resetTiming();
    return false;
  }
  if (step > period_ticks_) {
    const std::int64_t missed = step / period_ticks_ - 1;
    counters_.missed_samples.fetch_add(static_cast<std::uint64_t>(missed), std::memory_order_relaxed);
    report(i2c_.path(), "missed " + std::to_string(missed) + " sample" + (missed == 1 ? "" : "s") +
                            " (SENSORTIME step of " + std::to_string(step) + " ticks, expected " +
                            std::to_string(period_ticks_) + ")");
  }
  last_tick_ = tick;
  return true;
}

void Bmi263Source::feedFit(std::int64_t sample_tick, std::int64_t read_tick, std::int64_t read_ns,
                           const hal::EdgeEvent& edge) {
  // Pairing check: the edge must belong to `sample_tick`. Host time between
  // edge and read, minus device time between sample and read, is minus the
  // edge's latency for the right sample (<= 0, up to the 39 us tick
  // quantization), and positive by up to a period for the edge of an earlier
  // sample (a late read that already sees the next one). Such a pair would
  // sit below the true line, which the lower envelope must never see.
  const std::int64_t slack_ns = (read_ns - edge.t_ns) - ticksToNs(read_tick - sample_tick);
  if (slack_ns > config_.pairing_tolerance_ns) {
    counters_.unpaired_edges.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  switch (fit_.add(sample_tick, edge.t_ns)) {
    case SensorTimeFit::AddResult::kAccepted: break;
    case SensorTimeFit::AddResult::kRejectedOrder: break;
    case SensorTimeFit::AddResult::kRejectedOutlier:
      counters_.time_fit_rejections.fetch_add(1, std::memory_order_relaxed);
      break;
    case SensorTimeFit::AddResult::kReset:
      counters_.time_fit_resets.fetch_add(1, std::memory_order_relaxed);
      report(irq_.path(), "time fit restarted: interrupt times jumped against SENSORTIME");
      break;
  }
  counters_.oscillator_ppm.store(fit_.ratePpm(), std::memory_order_relaxed);
}

void Bmi263Source::emit(std::int64_t tick, const std::array<std::int16_t, 3>& accel,
                        const std::array<std::int16_t, 3>& gyro, std::int64_t fallback_ns) noexcept {
  std::int64_t t_ns = (fit_.hasEstimate() ? fit_.hostTimeNs(tick) : fallback_ns) - config_.sample_time_offset_ns;
  // Sinks need increasing time: a jitter step back is nudged past the last
  // stamp. A larger one means the last stamp was wrong (a bad SENSORTIME
  // read, a fit restart): nudging would chain every later sample to it,
  // 1 ns apart, so the time goes out as it is and the service's entrance
  // judges it (rilod/sample_screen.h).
  constexpr std::int64_t kMaxNudgeNs = 5'000'000;
  if (has_emitted_ && t_ns <= last_emitted_ns_ && last_emitted_ns_ - t_ns < kMaxNudgeNs) t_ns = last_emitted_ns_ + 1;
  has_emitted_ = true;
  last_emitted_ns_ = t_ns;
  ImuSample sample;
  sample.t_ns = t_ns;
  const double accel_scale = driver_.accelScale();
  const double gyro_scale = driver_.gyroScale();
  sample.accel_m_s2 = Eigen::Vector3d(accel[0], accel[1], accel[2]) * accel_scale;
  std::array<std::int16_t, 3> g = gyro;
  if (driver_.gyroCrossAxis()) correctGyroCrossAxis(g, driver_.gyroCas());
  sample.gyro_rad_s = Eigen::Vector3d(g[0], g[1], g[2]) * gyro_scale;
  counters_.samples.fetch_add(1, std::memory_order_relaxed);
  sink_->push(Sample(sample));
}

void Bmi263Source::maybeReadTemperature() {
  if (config_.temperature_period_ns == 0) return;
  const std::int64_t now_ns = clock_.nowNs();
  if (now_ns < next_temperature_ns_) return;
  next_temperature_ns_ = now_ns + config_.temperature_period_ns;
  double degc = 0.0;
  if (driver_.readTemperature(degc)) {
    report(i2c_.path(), "temperature: " + driver_.lastBusError());
    return;
  }
  counters_.temperature_reads.fetch_add(1, std::memory_order_relaxed);
  counters_.temperature_degc.store(degc, std::memory_order_relaxed);
}

Bmi263Source::Step Bmi263Source::serviceDataReady(const hal::EdgeEvent* edge) {
  const std::int64_t read_ns = clock_.nowNs();
  RawImuData raw;
  if (driver_.readData(raw)) return onReadFailure();
  read_failures_in_row_ = 0;
  const std::int64_t read_tick = unwrapper_.unwrap(raw.sensortime, edge != nullptr ? edge->t_ns : read_ns);
  // Data registers update on multiples of the period in SENSORTIME, and the
  // burst is consistent (shadowed): the sample's own tick is the read tick
  // rounded down to the period.
  const std::int64_t tick = floorDiv(read_tick, period_ticks_) * period_ticks_;
  if (!acceptTick(tick)) return Step::kContinue;
  if (edge != nullptr) feedFit(tick, read_tick, read_ns, *edge);
  emit(tick, raw.accel, raw.gyro, read_ns - ticksToNs(read_tick - tick));
  maybeReadTemperature();
  return Step::kContinue;
}

Bmi263Source::Step Bmi263Source::serviceFifo(const hal::EdgeEvent* edge) {
  const std::int64_t p = period_ticks_;
  const std::size_t watermark_frames = config_.fifo_watermark_frames;
  for (int round = 0; round < 4; ++round) {
    const bool first_round = round == 0;
    const std::int64_t read_ns = clock_.nowNs();
    std::size_t length = 0;
    if (driver_.readFifoLength(length)) return onReadFailure();
    if (length == 0) {
      if (first_round && edge != nullptr) counters_.duplicate_reads.fetch_add(1, std::memory_order_relaxed);
      break;
    }
    // One read: the stored bytes plus room for the sensortime frame the part
    // appends after the last frame.
    const std::size_t n = std::min(length + fifo::kSensorTimeFrameBytes, fifo_buffer_.size());
    const std::span<std::uint8_t> bytes(fifo_buffer_.data(), n);
    if (driver_.readFifo(bytes)) return onReadFailure();
    read_failures_in_row_ = 0;
    const FifoParseResult parsed = fifo_parser_.parse(bytes);
    const std::span<const FifoDataFrame> frames = fifo_parser_.frames(parsed);
    const auto count = static_cast<std::int64_t>(frames.size());

    if (parsed.skipped_frames > 0) {
      counters_.fifo_overflows.fetch_add(1, std::memory_order_relaxed);
      counters_.fifo_frames_lost.fetch_add(parsed.skipped_frames, std::memory_order_relaxed);
      report(i2c_.path(), "FIFO overflow: " + std::to_string(parsed.skipped_frames) + " frames dropped by the part");
    }
    if (parsed.unknown_header) {
      counters_.fifo_parse_errors.fetch_add(1, std::memory_order_relaxed);
      char header[8];
      std::snprintf(header, sizeof header, "0x%02X", static_cast<unsigned>(parsed.bad_header));
      report(i2c_.path(), std::string("FIFO: unknown frame header ") + header + ", FIFO flushed");
      if (driver_.flushFifo()) return onReadFailure();
    }

    // Sample ticks: anchored on the sensortime frame (its value rounded down
    // to the period is the last frame's tick), else counted on from the last.
    std::int64_t first_tick = 0;
    std::int64_t read_tick = 0;
    const bool anchored = parsed.has_sensortime;
    if (anchored) {
      read_tick = unwrapper_.unwrap(parsed.sensortime_raw, read_ns);
      first_tick = floorDiv(read_tick, p) * p - (count - 1) * p;
    } else if (has_last_tick_) {
      first_tick = last_tick_ + (1 + static_cast<std::int64_t>(parsed.skipped_frames)) * p;
    } else if (count > 0) {
      // Nothing to time these frames against yet: drop them.
      counters_.missed_samples.fetch_add(static_cast<std::uint64_t>(count), std::memory_order_relaxed);
      report(i2c_.path(), "FIFO: " + std::to_string(count) + " frames without a sensortime anchor dropped");
    }

    if (count > 0 && (anchored || has_last_tick_)) {
      // Time fit: after a drain, the watermark edge is the watermark_frames-th frame.
      if (first_round && edge != nullptr) {
        if (anchored && fifo_drained_ && parsed.skipped_frames == 0 &&
            frames.size() >= watermark_frames) {
          feedFit(first_tick + static_cast<std::int64_t>(watermark_frames - 1) * p, read_tick, read_ns, *edge);
        } else {
          counters_.unpaired_edges.fetch_add(1, std::memory_order_relaxed);
        }
      }
      for (std::int64_t i = 0; i < count; ++i) {
        const std::int64_t tick = first_tick + i * p;
        if (!acceptTick(tick)) continue;
        const FifoDataFrame& frame = frames[static_cast<std::size_t>(i)];
        emit(tick, frame.accel_raw, frame.gyro_raw, read_ns - (anchored ? ticksToNs(read_tick - tick) : 0));
      }
    }
    fifo_drained_ = parsed.reached_end || parsed.unknown_header;
    if (parsed.reached_end || length + fifo::kSensorTimeFrameBytes <= fifo_buffer_.size()) break;
  }
  maybeReadTemperature();
  return Step::kContinue;
}

}  // namespace rilo::bmi263
