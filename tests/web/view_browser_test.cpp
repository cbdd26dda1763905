// `rilo view` in a real browser (ctest -L web): rilod replays the demo office
// live on a private loopback domain, `rilo view` serves its page, and a
// headless Chromium (Debian's, installed by cmake/debian-test-packages.txt) opens
// it and is asked what a person would see: the anchors drawn, the state, a
// pose that moves. A screenshot is kept in build/web-artifacts/.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "hal/recording/recording_reader.h"
#include "service/rilod_runner.h"
#include "web/cdp_pipe.h"
#include "web/rilo_process.h"

namespace rilo {
namespace {

using namespace std::chrono_literals;

TEST(RiloViewInABrowser, ThePageShowsTheAnchorsTheStateAndAMovingPose) {
  const std::string chromium = testing::findChromium();
  ASSERT_FALSE(chromium.empty()) << "no chromium: the README's test command installs it (cmake/debian-test-packages.txt)";
  testing::TempDir dir("rilo-view-web");
  const std::filesystem::path rec = testing::sourceDir() / "tests" / "data" / "office-demo";
  const std::size_t anchor_count = readRecording(rec).anchors.size();
  testing::writeFile(dir / "rilod.yaml",
                     "sources:\n  mode: replay\n  replay:\n    path: " + rec.string() +
                         "\n    pace: real_time\n    speed: 1.0\n    shift_to_now: true\n"
                         "anchors:\n  file: " + rec.string() + "/anchors.csv\n"
                         "estimator:\n  range:\n    lever_arm_m: [0.06, 0.0, 0.10]\n"
                         "dds:\n  domain: " + std::to_string(testing::testDomain()) + "\n  loopback_only: true\n");

  testing::ChildProcess view(testing::startRilo({"view", "--config", (dir / "rilod.yaml").string(), "--port", "0", "--seconds", "120"},
                               dir / "view.out"));
  ASSERT_GT(view.pid(), 0);
  const std::string url = testing::waitForUrl(dir / "view.out", 20s);
  ASSERT_FALSE(url.empty()) << "rilo view printed no URL";
  testing::ChildProcess rilod(testing::startRilod(dir / "rilod.yaml", 60.0, dir / "rilod.log"));
  ASSERT_GT(rilod.pid(), 0);

  nlohmann::json seen, first_tracking, stale;
  std::string screenshot;
  {
    testing::HeadlessChromium browser(chromium, dir / "chromium-profile");
    const std::string page = browser.open(url, 1280, 800);
    // Null until the page's script ran (the new target starts as about:blank).
    const std::string probe =
        "window.riloView === undefined ? null : JSON.stringify({state: document.getElementById('state').textContent,"
        " reason: document.getElementById('reason').textContent,"
        " pose: document.getElementById('pose-text').textContent,"
        " connection: document.getElementById('connection').textContent,"
        " anchors: window.riloView.anchorsDrawn, poseDrawn: window.riloView.poseDrawn,"
        " events: window.riloView.events, ranges: window.riloView.rangesShown,"
        " verdicts: Array.from(document.querySelectorAll('#anchors td.nlos, #anchors td.los')).map(td => td.textContent)})";
    // Tracking within the demo's first seconds (the initializer needs ~10 s of data).
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(static_cast<int>(45 * testing::timeScale()));
    while (std::chrono::steady_clock::now() < end) {
      const nlohmann::json value = browser.evaluate(page, probe);
      if (value.is_string()) {
        seen = nlohmann::json::parse(value.get<std::string>());
        if ((seen["state"] == "tracking" || seen["state"] == "degraded") && seen["poseDrawn"] == true) break;
      }
      std::this_thread::sleep_for(250ms);
    }
    ASSERT_TRUE(seen.is_object()) << "the page never ran its script";
    first_tracking = seen;
    std::this_thread::sleep_for(2s);  // a walking person moves in 2 s
    const nlohmann::json later = browser.evaluate(page, probe);
    ASSERT_TRUE(later.is_string()) << later;
    seen = nlohmann::json::parse(later.get<std::string>());
    screenshot = browser.screenshotPng(page);
    // The service stops: within a few seconds the page says it shows the past.
    rilod.stop();
    std::this_thread::sleep_for(std::chrono::milliseconds(static_cast<int>(4500 * testing::timeScale())));
    const nlohmann::json after = browser.evaluate(page, probe);
    ASSERT_TRUE(after.is_string()) << after;
    stale = nlohmann::json::parse(after.get<std::string>());
  }
  rilod.stop();
  view.stop();

  std::printf("page at first tracking: %s\npage 2 s later: %s\n", first_tracking.dump().c_str(), seen.dump().c_str());
  EXPECT_TRUE(first_tracking["state"] == "tracking" || first_tracking["state"] == "degraded") << first_tracking;
  EXPECT_EQ(seen["anchors"], anchor_count) << "every anchor of the configuration drawn";
  EXPECT_EQ(seen["connection"], "live");
  EXPECT_EQ(seen["poseDrawn"], true);
  EXPECT_GT(seen["events"].get<int>(), first_tracking["events"].get<int>()) << "the server keeps pushing";
  EXPECT_NE(seen["pose"], first_tracking["pose"]) << "the pose moves";
  EXPECT_EQ(seen["pose"].get<std::string>().rfind("x ", 0), 0u) << seen["pose"];
  // Per anchor: its newest range, residual and the estimator's verdict.
  EXPECT_GE(seen["ranges"].get<int>(), 4) << "most anchors ranged within the walk's first seconds";
  EXPECT_EQ(seen["verdicts"].size(), seen["ranges"].get<std::size_t>());
  for (const auto& v : seen["verdicts"]) {
    const std::string text = v.get<std::string>();
    EXPECT_TRUE(text.rfind("LOS", 0) == 0 || text.rfind("NLOS", 0) == 0) << text;
  }
  std::printf("page 4.5 s after rilod stopped: %s\n", stale.dump().c_str());
  EXPECT_EQ(stale["connection"].get<std::string>().rfind("no data for ", 0), 0u) << stale;

  // The screenshot, kept for people to look at (a PNG, 1280 x 800).
  ASSERT_GT(screenshot.size(), 10'000u);
  EXPECT_EQ(screenshot.substr(1, 3), "PNG");
  const std::filesystem::path artifacts = testing::binaryDir().parent_path() / "web-artifacts";
  std::filesystem::create_directories(artifacts);
  std::ofstream(artifacts / "rilo-view.png", std::ios::binary) << screenshot;
  std::printf("screenshot: %s (%zu bytes)\n", (artifacts / "rilo-view.png").c_str(), screenshot.size());
}

}  // namespace
}  // namespace rilo
