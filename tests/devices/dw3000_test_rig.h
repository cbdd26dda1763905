#pragma once
// Test rig for the DW3000 driver: virtual clock, emulated IRQ and reset
// lines, the register-level emulator with responders, a matching driver
// configuration and a sink that collects samples and faults.
#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <variant>
#include <vector>

#include "devices/emulation/dw3000_emulator.h"
#include "devices/emulation/virtual_time.h"
#include "hal/dw3000/dw3000_config.h"
#include "hal/dw3000/dw3000_source.h"
#include "hal/source.h"

namespace rilo::dw3000::testing {

class CollectingSink final : public SampleSink {
 public:
  void push(const Sample& sample) noexcept override {
    if (const auto* range = std::get_if<RangeSample>(&sample)) ranges.push_back(*range);
  }
  void fault(const SourceFault& f) noexcept override { faults.push_back(f); }
  void note(const SourceNote& n) noexcept override { notes.push_back(n); }

  std::size_t rangesFrom(std::uint32_t anchor_id, std::int64_t after_ns = 0) const {
    std::size_t n = 0;
    for (const RangeSample& r : ranges) n += (r.anchor_id == anchor_id && r.t_ns >= after_ns) ? 1 : 0;
    return n;
  }
  std::size_t faultsContaining(const std::string& text) const {
    std::size_t n = 0;
    for (const SourceFault& f : faults) n += f.what.find(text) != std::string::npos ? 1 : 0;
    return n;
  }

  std::vector<RangeSample> ranges;
  std::vector<SourceFault> faults;
  std::vector<SourceNote> notes;
};

struct Rig {
  explicit Rig(emu::Dw3000EmulatorParams params = {}, bool with_reset_line = true)
      : chip(clock, irq, with_reset_line ? &reset : nullptr, std::move(params)),
        reset_line(with_reset_line ? &reset : nullptr) {
    config.pan_id = 0xDECA;
    config.tag_address = 0x8000;
  }

  /// An anchor known to both the emulator and the driver configuration.
  std::size_t addAnchor(std::uint32_t id, std::uint16_t address, std::function<double(std::int64_t)> distance_m,
                        double clock_ppm = 0.0) {
    emu::Dw3000ResponderModel model;
    model.short_address = address;
    model.pan_id = config.pan_id;
    model.channel = static_cast<int>(config.channel);
    model.preamble_code = config.preamble_code;
    model.distance_m = std::move(distance_m);
    model.clock_ppm = clock_ppm;
    model.reply_delay_us = config.reply_delay_us;
    config.anchors.push_back(AnchorConfig{id, address});
    return chip.addResponder(std::move(model));
  }
  std::size_t addAnchor(std::uint32_t id, std::uint16_t address, double distance_m, double clock_ppm = 0.0) {
    return addAnchor(id, address, [distance_m](std::int64_t) { return distance_m; }, clock_ppm);
  }

  /// Run `source` for `duration_ns` of virtual time (or until it ends).
  SourceEnd run(Dw3000Source& source, CollectingSink& sink, std::int64_t duration_ns) {
    stop = false;
    clock.schedule(clock.nowNs() + duration_ns, [this] { stop = true; });
    return source.run(sink, stop);
  }

  emu::VirtualClock clock{1'000'000'000};
  emu::EmulatedInterruptLine irq{clock, "emu:gpiochip0:17"};
  emu::EmulatedOutputLine reset{"emu:gpiochip0:27"};
  emu::Dw3000Emulator chip;
  hal::OutputLine* reset_line;
  Dw3000Config config;
  std::atomic<bool> stop{false};
};

}  // namespace rilo::dw3000::testing
