#pragma once
// BMI263 as a rilo::SampleSource: brings the part up, then loops on its INT1
// line, turning every data-ready (or FIFO watermark) interrupt into ImuSamples
// in SI units stamped on the host clock (CLOCK_MONOTONIC on the board), and
// every fault into a counted SourceFault. Never throws out of run() for device
// trouble: faults are retried, counted, reported, recovered from by a new
// bring-up, and only reported fatal when recovery is exhausted.
//
// Timestamps: see sensor_time_fit.h (lower-envelope fit of edge time against
// the unwrapped SENSORTIME) and hal/bmi263/README.md.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "hal/bmi263/bmi263_config.h"
#include "hal/bmi263/bmi263_driver.h"
#include "hal/bmi263/bmi263_fifo_parser.h"
#include "hal/bmi263/sensor_time_fit.h"
#include "hal/bus/clock.h"
#include "hal/bus/gpio_line.h"
#include "hal/bus/i2c_device.h"
#include "hal/source.h"

namespace rilo::bmi263 {

/// Counters of a running source (snapshot; safe to take from another thread).
struct Bmi263Counters {
  std::uint64_t samples = 0;               ///< ImuSamples pushed
  std::uint64_t missed_samples = 0;        ///< from sensortime steps (includes FIFO overflow losses)
  std::uint64_t duplicate_reads = 0;       ///< interrupt without a new sample
  std::uint64_t sensortime_backwards = 0;  ///< sample tick went back (device reset behind our back)
  std::uint64_t i2c_retries = 0;           ///< transfers repeated after an error
  std::uint64_t i2c_failures = 0;          ///< transfers failed after all retries
  std::uint64_t irq_timeouts = 0;
  std::uint64_t irq_errors = 0;
  std::uint64_t stuck_irq = 0;             ///< timeout with the line high: serviced without an edge
  std::uint64_t fifo_overflows = 0;        ///< reads that carried skip frames
  std::uint64_t fifo_frames_lost = 0;      ///< frames the skip frames reported
  std::uint64_t fifo_parse_errors = 0;     ///< unknown FIFO header (FIFO flushed)
  std::uint64_t unpaired_edges = 0;        ///< edges not used for the time fit (ambiguous pairing)
  std::uint64_t time_fit_rejections = 0;   ///< edge stamps below the fitted line
  std::uint64_t time_fit_resets = 0;
  std::uint64_t bring_ups = 0;             ///< successful bring-ups (1 + recoveries)
  std::uint64_t bring_up_failures = 0;
  std::uint64_t recoveries = 0;            ///< re-bring-ups after repeated faults
  std::uint64_t temperature_reads = 0;
  std::uint64_t faults_reported = 0;
  double temperature_degc = 0.0;           ///< last reading (NaN before the first)
  double oscillator_ppm = 0.0;             ///< fitted IMU clock rate error (positive: counts fast)
};

class Bmi263Source final : public SampleSource {
 public:
  /// The bus, line and clock must outlive the source. Throws
  /// std::invalid_argument (from config.validate()) for a bad configuration.
  Bmi263Source(hal::I2cDevice& i2c, hal::InterruptLine& irq, hal::Clock& clock, Bmi263Config config);

  SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) override;
  std::string describe() const override;

  Bmi263Counters counters() const noexcept;
  const Bmi263Config& config() const noexcept { return config_; }

 private:
  enum class Step { kContinue, kRestart, kFatal };

  /// Brings the part up (retrying); `at_startup` false: a re-initialization.
  bool startDevice(const std::atomic<bool>& stop, bool at_startup);
  /// Tells the sink what the start-up read and applied (SourceNote).
  void noteStartUp(const BringUpResult& result, bool at_startup) noexcept;
  void discardStaleEdges();
  void resetTiming() noexcept;
  Step serviceDataReady(const hal::EdgeEvent* edge);
  Step serviceFifo(const hal::EdgeEvent* edge);
  Step onReadFailure();
  Step onTimeout();
  Step onIrqError(const std::error_code& error);
  /// Sample tick bookkeeping: returns false if the sample must not be emitted.
  bool acceptTick(std::int64_t tick);
  void feedFit(std::int64_t sample_tick, std::int64_t read_tick, std::int64_t read_ns, const hal::EdgeEvent& edge);
  void emit(std::int64_t tick, const std::array<std::int16_t, 3>& accel, const std::array<std::int16_t, 3>& gyro,
            std::int64_t fallback_ns) noexcept;
  void maybeReadTemperature();
  void report(const std::string& device, const std::string& what, bool fatal = false);

  hal::I2cDevice& i2c_;
  hal::InterruptLine& irq_;
  hal::Clock& clock_;
  Bmi263Config config_;
  Bmi263Driver driver_;
  SensorTimeFit fit_;
  SensorTimeUnwrapper unwrapper_;
  FifoParser fifo_parser_;
  std::vector<std::uint8_t> fifo_buffer_;  // allocated once
  std::int64_t period_ticks_;
  SampleSink* sink_ = nullptr;

  // Sample continuity and timing state (reset with the device).
  bool has_last_tick_ = false;
  std::int64_t last_tick_ = 0;
  bool fifo_drained_ = false;
  std::int64_t last_emitted_ns_ = 0;
  bool has_emitted_ = false;
  std::int64_t next_temperature_ns_ = 0;
  int timeouts_in_row_ = 0;
  int read_failures_in_row_ = 0;
  int irq_errors_in_row_ = 0;
  bool has_pending_edge_ = false;  // a fresh edge met while discarding stale ones
  hal::EdgeEvent pending_edge_;

  struct AtomicCounters {
    std::atomic<std::uint64_t> samples{0}, missed_samples{0}, duplicate_reads{0}, sensortime_backwards{0},
        irq_timeouts{0}, irq_errors{0}, stuck_irq{0}, fifo_overflows{0}, fifo_frames_lost{0},
        fifo_parse_errors{0}, unpaired_edges{0}, time_fit_rejections{0}, time_fit_resets{0}, bring_ups{0},
        bring_up_failures{0}, recoveries{0}, temperature_reads{0}, faults_reported{0};
    std::atomic<double> temperature_degc;
    std::atomic<double> oscillator_ppm{0.0};
  };
  AtomicCounters counters_;
};

}  // namespace rilo::bmi263
