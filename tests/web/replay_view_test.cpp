// `rilo replay REC --view`: the recording live through the service, and the
// same page over it; read here through the page's own /state (the browser
// test reads the page itself).
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "hal/recording/recording_reader.h"
#include "web/rilo_process.h"

// After Eigen (the recording reader): see view_state_test.cpp.
#include <httplib.h>

namespace rilo {
namespace {

using namespace std::chrono_literals;

TEST(RiloReplayView, TheRecordingTracksLiveBehindThePageAndStopsOnSigterm) {
  testing::TempDir dir("rilo-replay-view");
  const std::filesystem::path rec = testing::sourceDir() / "tests" / "data" / "office-demo";
  testing::ChildProcess tool(testing::startRilo(
      {"replay", rec.string(), "--view", "--view-port", "0", "--view-speed", "2"}, dir / "replay.out"));
  ASSERT_GT(tool.pid(), 0);
  const std::string url = testing::waitForUrl(dir / "replay.out", 30s);
  ASSERT_EQ(url.rfind("http://127.0.0.1:", 0), 0u) << url;
  const int port = std::stoi(url.substr(std::string("http://127.0.0.1:").size()));
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(5, 0);

  nlohmann::json state;  // not const: a missing key reads as null and fails a check
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(static_cast<int>(30 * testing::timeScale()));
  while (std::chrono::steady_clock::now() < end) {
    if (const auto r = client.Get("/state"); r && r->status == 200) {
      state = nlohmann::json::parse(r->body);
      if (state["status"].is_object() && state["status"]["state"] == "tracking" && state["pose"].is_object() &&
          state["pose"]["source"] == "odometry") {
        break;
      }
    }
    std::this_thread::sleep_for(250ms);
  }
  std::this_thread::sleep_for(1s);  // a second of tracking at 2x: ~1600 IMU samples taken
  if (const auto r = client.Get("/state"); r && r->status == 200) state = nlohmann::json::parse(r->body);
  EXPECT_EQ(tool.stop(), 0) << "Ctrl-C / SIGTERM ends it cleanly";
  ASSERT_TRUE(state["status"].is_object()) << state;
  EXPECT_TRUE(state["status"]["state"] == "tracking" || state["status"]["state"] == "degraded") << state;
  EXPECT_EQ(state["anchors"].size(), readRecording(rec).anchors.size()) << "the recording's anchors";
  EXPECT_FALSE(state["pose"]["yaw_deg"].is_null());
  EXPECT_GT(state["received"]["odometry"].get<int>(), 800) << "odometry at the IMU rate";
  EXPECT_GE(state["age_s"]["status"].get<double>(), 0.0);
}

}  // namespace
}  // namespace rilo
