// rilod logs what each device's start-up read and applied (the DW3000's OTP
// trims, PLL lock, DGC and PGF calibration; the BMI263's chip id and config
// blob): the first thing a board bring-up looks for in the journal. The real
// service on the emulated board; its on_note callback is what rilod logs.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "rilod/config.h"
#include "rilod/hardware_sources.h"
#include "rilod/service.h"
#include "rilod/service_setup.h"
#include "rilod_runner.h"
#include "service/emulated_board.h"
#include "service/service_test_support.h"

namespace rilo {
namespace {

using namespace std::chrono_literals;

TEST(DeviceNotes, RilodLogsWhatEachDevicesStartUpReadAndApplied) {
  testing::TempDir dir("device-notes");
  testing::writeBlob(dir / "blob.bin");
  testing::BoardTruth truth;
  for (std::uint32_t id = 0; id < 4; ++id) truth.responders[id] = {3.0 + id, 0.0};
  const ServiceConfig cfg = parseServiceConfig(
      testing::boardYaml("dds:\n  domain: " + std::to_string(testing::testDomain()) +
                         "\n  loopback_only: true\nrealtime:\n  lock_memory: false\n"),
      dir / "rilod.yaml");
  testing::EmulatedBoard board(cfg.sources.hardware, truth);
  ServiceOptions options = serviceOptions(cfg);
  std::mutex mutex;
  std::vector<std::string> events;
  options.on_note = [&](const SourceNote& n) {  // from both source threads
    const std::lock_guard<std::mutex> lock(mutex);
    events.push_back(n.device + ": " + n.what);
  };
  auto notesSeen = [&] {
    const std::lock_guard<std::mutex> lock(mutex);
    int seen = 0;
    for (const std::string& e : events) {
      seen += e.rfind("emu:spidev0.0: started: ", 0) == 0 || e.rfind("emu:bmi263@0x68: started: ", 0) == 0;
    }
    return seen;
  };
  Service service(std::move(options), makeHardwareSources(cfg.sources.hardware, board.uwb(), board.imu()));
  std::atomic<bool> stop{false};
  int code = -1;
  std::thread runner([&] { code = service.run(stop); });
  const auto deadline = std::chrono::steady_clock::now() +
                        std::chrono::duration_cast<std::chrono::steady_clock::duration>(30s * testing::timeScale());
  while (notesSeen() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(10ms);
  stop.store(true);
  runner.join();
  EXPECT_EQ(code, 0);

  std::string all;
  for (const std::string& e : events) all += "  " + e + "\n";
  ASSERT_EQ(notesSeen(), 2) << all;
  std::printf("rilod's device notes on the emulated board:\n%s", all.c_str());
  for (const std::string& e : events) {
    if (e.rfind("emu:spidev0.0: ", 0) == 0) {
      EXPECT_NE(e.find("XTAL trim"), std::string::npos) << e;
      EXPECT_NE(e.find("PLL lock"), std::string::npos) << e;
      EXPECT_NE(e.find("PGF calibration done"), std::string::npos) << e;
    }
    if (e.rfind("emu:bmi263@0x68: ", 0) == 0) {
      EXPECT_NE(e.find("chip id 0x24"), std::string::npos) << e;
      EXPECT_NE(e.find("blob.bin' loaded"), std::string::npos) << e;
    }
  }
}

}  // namespace
}  // namespace rilo
