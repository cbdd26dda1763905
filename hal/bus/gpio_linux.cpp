#include "hal/bus/gpio_linux.h"

#include <gpiod.h>
#include <sys/utsname.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>

namespace rilo::hal {
namespace {

std::int64_t toNs(const timespec& ts) noexcept {
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

std::int64_t clockNs(clockid_t id) noexcept {
  timespec ts{};
  clock_gettime(id, &ts);
  return toNs(ts);
}

std::string errnoText(int err) { return std::strerror(err); }

// Opens the chip by name or by path; throws with the name and strerror.
gpiod_chip* openChip(const std::string& chip, unsigned offset) {
  if (chip.empty()) throw std::invalid_argument("GPIO: chip name is empty");
  gpiod_chip* handle =
      chip.front() == '/' ? gpiod_chip_open(chip.c_str()) : gpiod_chip_open_by_name(chip.c_str());
  if (handle == nullptr) {
    const int err = errno;
    const std::string where = chip.front() == '/' ? chip : chip + " (/dev/" + chip + ")";
    throw std::runtime_error("GPIO: cannot open chip " + where + " for line " + std::to_string(offset) + ": " +
                             errnoText(err));
  }
  return handle;
}

}  // namespace

bool kernelGpioEventsAreMonotonic() noexcept {
  utsname name{};
  if (uname(&name) != 0) return true;
  int major = 0;
  int minor = 0;
  if (std::sscanf(name.release, "%d.%d", &major, &minor) != 2) return true;
  return major > 5 || (major == 5 && minor >= 7);
}

GpioInterruptLine::GpioInterruptLine(const std::string& chip, unsigned offset, const std::string& consumer)
    : monotonic_events_(kernelGpioEventsAreMonotonic()) {
  chip_ = openChip(chip, offset);
  path_ = std::string(gpiod_chip_name(chip_)) + ":" + std::to_string(offset);
  line_ = gpiod_chip_get_line(chip_, offset);
  if (line_ == nullptr) {
    const int err = errno;
    gpiod_chip_close(chip_);
    throw std::runtime_error("GPIO: no line " + path_ + ": " + errnoText(err));
  }
  if (gpiod_line_request_rising_edge_events(line_, consumer.c_str()) != 0) {
    const int err = errno;
    gpiod_chip_close(chip_);
    throw std::runtime_error("GPIO: cannot request rising-edge events on " + path_ + ": " + errnoText(err));
  }
}

GpioInterruptLine::~GpioInterruptLine() {
  if (chip_ != nullptr) gpiod_chip_close(chip_);  // also releases the line
}

WaitResult GpioInterruptLine::waitEdge(std::chrono::nanoseconds timeout, EdgeEvent& event,
                                       std::error_code& error) noexcept {
  const std::int64_t timeout_ns = timeout.count() > 0 ? timeout.count() : 0;
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(timeout_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(timeout_ns % 1'000'000'000);
  const int ready = gpiod_line_event_wait(line_, &ts);
  if (ready < 0) {
    error = {errno, std::system_category()};
    return WaitResult::kError;
  }
  if (ready == 0) return WaitResult::kTimeout;
  gpiod_line_event raw{};
  if (gpiod_line_event_read(line_, &raw) != 0) {
    error = {errno, std::system_category()};
    return WaitResult::kError;
  }
  std::int64_t t_ns = toNs(raw.ts);
  if (!monotonic_events_) {
    // Pre-5.7 kernel: the stamp is CLOCK_REALTIME; move it to MONOTONIC.
    const std::int64_t realtime_ns = clockNs(CLOCK_REALTIME);
    const std::int64_t monotonic_ns = clockNs(CLOCK_MONOTONIC);
    t_ns -= realtime_ns - monotonic_ns;
  }
  event.t_ns = t_ns;
  event.rising = raw.event_type == GPIOD_LINE_EVENT_RISING_EDGE;
  return WaitResult::kEdge;
}

std::error_code GpioInterruptLine::readLevel(bool& high) noexcept {
  const int value = gpiod_line_get_value(line_);
  if (value < 0) return {errno, std::system_category()};
  high = value != 0;
  return {};
}

GpioOutputLine::GpioOutputLine(const std::string& chip, unsigned offset, bool initial_high,
                               const std::string& consumer) {
  chip_ = openChip(chip, offset);
  path_ = std::string(gpiod_chip_name(chip_)) + ":" + std::to_string(offset);
  line_ = gpiod_chip_get_line(chip_, offset);
  if (line_ == nullptr) {
    const int err = errno;
    gpiod_chip_close(chip_);
    throw std::runtime_error("GPIO: no line " + path_ + ": " + errnoText(err));
  }
  if (gpiod_line_request_output(line_, consumer.c_str(), initial_high ? 1 : 0) != 0) {
    const int err = errno;
    gpiod_chip_close(chip_);
    throw std::runtime_error("GPIO: cannot request " + path_ + " as output: " + errnoText(err));
  }
}

GpioOutputLine::~GpioOutputLine() {
  if (chip_ != nullptr) gpiod_chip_close(chip_);
}

std::error_code GpioOutputLine::set(bool high) noexcept {
  if (gpiod_line_set_value(line_, high ? 1 : 0) != 0) return {errno, std::system_category()};
  return {};
}

}  // namespace rilo::hal
