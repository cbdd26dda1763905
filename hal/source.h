#pragma once
// The one interface every sample source implements: hardware drivers, replay
// of a recording and the simulator. The service cannot tell them apart.
//
// A source pushes samples into a sink from the thread that calls run(); the
// service runs each source in its own thread with a sink that writes into a
// lock-free queue, the offline tools call run() directly with a sink that
// processes synchronously (deterministic, as fast as possible).
#include <atomic>
#include <cstdint>
#include <string>
#include <variant>

#include "sensors/samples.h"

namespace rilo {

using Sample = std::variant<ImuSample, RangeSample, TdoaSample, UltrasonicSample>;

/// A fault a source recovered from (or could not): counted by the service and
/// shown on the status topic and in the log. Rare path: may allocate.
struct SourceFault {
  std::int64_t t_ns = 0;
  std::string device;   ///< "/dev/spidev0.0", "replay:/data/rec/imu.csv"
  std::string what;     ///< "RX timeout", "I2C NACK at reg 0x0C (EIO)"
  bool fatal = false;   ///< the source stopped because of it
};

/// What a source did that a bring-up engineer wants in the log: a device
/// started or re-initialized, and what its start-up read and applied. Rare
/// path: may allocate.
struct SourceNote {
  std::int64_t t_ns = 0;
  std::string device;  ///< "/dev/spidev0.0"
  std::string what;    ///< "started: XTAL trim 0x2E from OTP; PLL lock 48 us; ..."
};

class SampleSink {
 public:
  virtual ~SampleSink() = default;
  /// Called for every sample in time order per source. Must not block for
  /// long (hardware sources lose samples otherwise).
  virtual void push(const Sample& sample) noexcept = 0;
  virtual void fault(const SourceFault& fault) noexcept = 0;
  /// The source's loop is alive without a sample or fault to give (a wait
  /// timed out, a paced replay sleeps): the service's watchdog sees its
  /// thread beat. Called at least every few hundred milliseconds; wrappers
  /// forward it.
  virtual void idle() noexcept {}
  /// A note for the log (SourceNote); ignored unless the sink logs. Wrappers forward it.
  virtual void note(const SourceNote& /*note*/) noexcept {}
};

enum class SourceEnd { kStopped, kEndOfData, kFailed };

class SampleSource {
 public:
  virtual ~SampleSource() = default;
  /// Produce samples until `stop` becomes true, the data ends, or a fatal
  /// fault. Called once, from the thread that owns the source.
  virtual SourceEnd run(SampleSink& sink, const std::atomic<bool>& stop) = 0;
  /// For logs and status ("replay /data/office1 (paced x1.0)", "dwm3000 /dev/spidev0.0").
  virtual std::string describe() const = 0;
};

}  // namespace rilo
