#pragma once
// GPIO lines seen by drivers: an interrupt input whose edges carry the
// kernel's CLOCK_MONOTONIC timestamp (the one clock of the system), and an
// output (reset pin). Back-end: libgpiod 1.6; emulators in tests.
#include <chrono>
#include <cstdint>
#include <string>
#include <system_error>

namespace rilo::hal {

enum class WaitResult { kEdge, kTimeout, kError };

struct EdgeEvent {
  std::int64_t t_ns = 0;  ///< kernel event time, CLOCK_MONOTONIC (ns)
  bool rising = true;
};

class InterruptLine {
 public:
  virtual ~InterruptLine() = default;
  /// Wait up to `timeout` for the next edge; on kEdge `event` is filled, on
  /// kError `error` says why. Edges queued while nobody waited are returned
  /// first, oldest first (the kernel keeps 16 per line).
  virtual WaitResult waitEdge(std::chrono::nanoseconds timeout, EdgeEvent& event,
                              std::error_code& error) noexcept = 0;
  /// Current level (to detect a line stuck high after a missed edge).
  virtual std::error_code readLevel(bool& high) noexcept = 0;
  virtual const std::string& path() const noexcept = 0;  ///< "gpiochip0:17"
};

class OutputLine {
 public:
  virtual ~OutputLine() = default;
  virtual std::error_code set(bool high) noexcept = 0;
  virtual const std::string& path() const noexcept = 0;
};

}  // namespace rilo::hal
