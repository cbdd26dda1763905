#pragma once
// Shared pieces of the BMI263 tests: a blob file on disk, a recording sink, a
// smooth motion, and a rig wiring the emulator, the interrupt line, the
// virtual clock and the source together.
#include <atomic>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <memory>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "devices/emulation/bmi263_emulator.h"
#include "devices/emulation/virtual_time.h"
#include "hal/bmi263/bmi263_source.h"
#include "hal/source.h"

namespace rilo::bmi263::testing {

inline std::vector<std::uint8_t> makeBlob(std::size_t bytes, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<std::uint8_t> blob(bytes);
  for (auto& b : blob) b = static_cast<std::uint8_t>(rng() & 0xFF);
  return blob;
}

/// A file in the temp directory, removed again on destruction.
class TempFile {
 public:
  explicit TempFile(const std::vector<std::uint8_t>& bytes) {
    static std::atomic<int> counter{0};
    path_ = (std::filesystem::temp_directory_path() /
             ("rilo_bmi263_blob_" + std::to_string(::getpid()) + "_" + std::to_string(counter++) + ".bin"))
                .string();
    std::ofstream out(path_, std::ios::binary);
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  }
  ~TempFile() {
    std::error_code ignored;
    std::filesystem::remove(path_, ignored);
  }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

class RecordingSink final : public SampleSink {
 public:
  void push(const Sample& sample) noexcept override {
    const auto* imu = std::get_if<ImuSample>(&sample);
    if (imu == nullptr) return;
    if (on_sample) on_sample(*imu);
    if (keep_samples) samples.push_back(*imu);
    ++count;
  }
  void fault(const SourceFault& fault) noexcept override { faults.push_back(fault); }
  void note(const SourceNote& n) noexcept override { notes.push_back(n); }

  bool hasFault(const std::string& text) const {
    for (const auto& f : faults) {
      if (f.what.find(text) != std::string::npos) return true;
    }
    return false;
  }
  std::string allFaults() const {
    std::string text;
    for (const auto& f : faults) text += (f.fatal ? "[fatal] " : "") + f.device + ": " + f.what + "\n";
    return text;
  }

  bool keep_samples = true;
  std::function<void(const ImuSample&)> on_sample;
  std::vector<ImuSample> samples;
  std::vector<SourceFault> faults;
  std::vector<SourceNote> notes;  ///< "started: ...", "re-initialized: ..."
  std::uint64_t count = 0;
};

/// Smooth motion well inside the smallest ranges (2 g, 125 dps).
inline emu::ImuTruth smoothMotion(std::int64_t t_ns) {
  const double t = static_cast<double>(t_ns) * 1e-9;
  constexpr double k2Pi = 2.0 * std::numbers::pi;
  emu::ImuTruth truth;
  truth.gyro_rad_s = Eigen::Vector3d(0.9 * std::sin(k2Pi * 0.7 * t), -0.6 * std::cos(k2Pi * 0.4 * t),
                                     0.4 * std::sin(k2Pi * 1.1 * t + 0.3));
  truth.accel_m_s2 = Eigen::Vector3d(3.0 * std::sin(k2Pi * 0.5 * t), -2.0 * std::cos(k2Pi * 0.9 * t),
                                     9.80665 + 1.5 * std::sin(k2Pi * 1.3 * t));
  return truth;
}

/// Emulator + line + clock + blob file + driver configuration.
struct Rig {
  explicit Rig(emu::Bmi263EmulatorConfig emu_config = {}, emu::MotionFunction motion = smoothMotion)
      : blob(makeBlob(8192, 7)), blob_file(blob), irq(clock, "emu:gpiochip0:17") {
    emu_config.expected_blob_checksum = emu::Bmi263Emulator::checksum(blob);
    emulator = std::make_unique<emu::Bmi263Emulator>(clock, irq, std::move(motion), emu_config);
    config.config_blob_path = blob_file.path();
  }

  /// Runs a fresh source until virtual time `t_stop_ns` (relative to now).
  SourceEnd runFor(std::int64_t duration_ns, RecordingSink& sink) {
    source = std::make_unique<Bmi263Source>(*emulator, irq, clock, config);
    stop.store(false);
    clock.schedule(clock.nowNs() + duration_ns, [this] { stop.store(true); });
    return source->run(sink, stop);
  }

  emu::VirtualClock clock;
  std::vector<std::uint8_t> blob;
  TempFile blob_file;
  emu::EmulatedInterruptLine irq;
  std::unique_ptr<emu::Bmi263Emulator> emulator;
  Bmi263Config config;
  std::unique_ptr<Bmi263Source> source;
  std::atomic<bool> stop{false};
};

}  // namespace rilo::bmi263::testing
