#pragma once
// libgpiod 1.6 back-ends of hal::InterruptLine (rising-edge events with the
// kernel's timestamp) and hal::OutputLine (reset pins). Thin on purpose: they
// are reviewed here and exercised on the board (no GPIO character devices on
// development and CI machines).
//
// Event clock: since Linux 5.7 the gpio character device stamps line events
// with CLOCK_MONOTONIC (ktime_get_ns), the one clock of the system. Before
// 5.7 the stamp is CLOCK_REALTIME; on such kernels this back-end converts the
// stamp to CLOCK_MONOTONIC with the REALTIME - MONOTONIC offset read right
// after the event (wrong by any step of the wall clock between the edge and
// the read: NTP slewing is harmless, a step is not). eventTimesAreMonotonic()
// tells which case applies.
//
// The kernel queues only 16 events per line: read from a real-time thread.
#include <chrono>
#include <string>
#include <system_error>

#include "hal/bus/gpio_line.h"

struct gpiod_chip;
struct gpiod_line;

namespace rilo::hal {

/// True if the running kernel stamps GPIO line events with CLOCK_MONOTONIC
/// (Linux >= 5.7, from uname's release).
bool kernelGpioEventsAreMonotonic() noexcept;

class GpioInterruptLine final : public InterruptLine {
 public:
  /// `chip`: "gpiochip0" (gpiod_chip_open_by_name) or a path starting with
  /// '/' ("/dev/gpiochip0", gpiod_chip_open). `offset`: line on that chip.
  /// Requests rising-edge events as `consumer`. Throws std::runtime_error
  /// with the chip/line and strerror text on failure (missing chip, offset
  /// out of range, line busy).
  GpioInterruptLine(const std::string& chip, unsigned offset, const std::string& consumer = "rilo");
  ~GpioInterruptLine() override;
  GpioInterruptLine(const GpioInterruptLine&) = delete;
  GpioInterruptLine& operator=(const GpioInterruptLine&) = delete;

  /// gpiod_line_event_wait then gpiod_line_event_read (oldest queued event).
  WaitResult waitEdge(std::chrono::nanoseconds timeout, EdgeEvent& event,
                      std::error_code& error) noexcept override;
  std::error_code readLevel(bool& high) noexcept override;
  const std::string& path() const noexcept override { return path_; }  ///< "gpiochip0:17"
  bool eventTimesAreMonotonic() const noexcept { return monotonic_events_; }

 private:
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  std::string path_;
  bool monotonic_events_ = true;
};

class GpioOutputLine final : public OutputLine {
 public:
  /// As GpioInterruptLine; the line is requested as an output driven to
  /// `initial_high` at once.
  GpioOutputLine(const std::string& chip, unsigned offset, bool initial_high,
                 const std::string& consumer = "rilo");
  ~GpioOutputLine() override;
  GpioOutputLine(const GpioOutputLine&) = delete;
  GpioOutputLine& operator=(const GpioOutputLine&) = delete;

  std::error_code set(bool high) noexcept override;
  const std::string& path() const noexcept override { return path_; }

 private:
  gpiod_chip* chip_ = nullptr;
  gpiod_line* line_ = nullptr;
  std::string path_;
};

}  // namespace rilo::hal
