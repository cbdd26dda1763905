// rilo view's state (what the page draws) and its HTTP server, without a
// browser: the JSON picture from DDS messages, and /, /state and /events
// through a real HTTP client on loopback.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <future>
#include <numbers>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "view/view_page.h"
#include "view/view_server.h"
#include "view/view_state.h"

// After Eigen (view_state.h): glibc's <resolv.h>, which httplib.h includes,
// defines a macro `_res` that breaks Eigen's headers included after it.
#include <httplib.h>

namespace rilo::tool {
namespace {

using namespace std::chrono_literals;
using nlohmann::json;

std::vector<Anchor> twoAnchors() {
  Anchor a0;
  a0.id = 0;
  a0.p_w_anchor = Vec3(0.25, 0.5, 2.5);
  Anchor a1;
  a1.id = 3;
  a1.p_w_anchor = Vec3(10.0, 8.0, 2.75);
  a1.kind = AnchorKind::kUltrasonic;
  return {a0, a1};
}

dds::OdometryMessage odometryAt(std::int64_t t_ns, double x, double y, double yaw_rad) {
  dds::OdometryMessage m;
  m.stamp_ns = t_ns;
  m.p_w_b = Eigen::Vector3d(x, y, 1.3);
  m.q_w_b = Eigen::Quaterniond(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  m.pose_covariance = dds::Mat6::Identity() * 0.01;
  m.pose_covariance(0, 1) = m.pose_covariance(1, 0) = 0.004;
  m.v_b = Eigen::Vector3d(1.2, 0.0, 0.0);
  return m;
}

TEST(ViewState, NothingYetIsNullsAndTheConfiguredAnchors) {
  const ViewState state(twoAnchors());
  json j = json::parse(state.json());
  ASSERT_EQ(j["anchors"].size(), 2u);
  EXPECT_EQ(j["anchors"][1]["id"], 3);
  EXPECT_EQ(j["anchors"][1]["kind"], "ultrasonic");
  EXPECT_EQ(j["anchors"][1]["z"], 2.75);
  EXPECT_TRUE(j["pose"].is_null());
  EXPECT_TRUE(j["status"].is_null());
  EXPECT_TRUE(j["trail"].empty());
  EXPECT_EQ(j["version"], 0);
}

TEST(ViewState, OdometryGivesThePoseHeadingCovarianceAndATrailBrokenAtPauses) {
  ViewState state(twoAnchors());
  // 2 s at 200 Hz, then a 3 s pause, then 1 s more.
  std::int64_t t = 1'000'000'000;
  for (int i = 0; i < 400; ++i, t += 5'000'000) state.onOdometry(odometryAt(t, 0.005 * i, 1.0, std::numbers::pi / 2));
  t += 3'000'000'000;
  for (int i = 0; i < 200; ++i, t += 5'000'000) state.onOdometry(odometryAt(t, 5.0, 1.0 + 0.005 * i, std::numbers::pi / 2));
  json j = json::parse(state.json());
  EXPECT_EQ(j["version"], 600);
  json& p = j["pose"];
  EXPECT_EQ(p["source"], "odometry");
  EXPECT_EQ(p["x"], 5.0);
  EXPECT_NEAR(p["y"].get<double>(), 1.995, 1e-9);
  EXPECT_NEAR(p["yaw_deg"].get<double>(), 90.0, 0.05);
  EXPECT_EQ(p["position_only"], false);
  EXPECT_DOUBLE_EQ(p["cov_xy"].get<double>(), 0.004);
  EXPECT_NEAR(p["sigma_z"].get<double>(), 0.1, 1e-12);
  EXPECT_NEAR(p["speed_m_s"].get<double>(), 1.2, 1e-9);
  // A point per 100 ms of stamps: 20 before the pause, 10 after, in two segments.
  ASSERT_EQ(j["trail"].size(), 2u);
  EXPECT_EQ(j["trail"][0].size(), 20u);
  EXPECT_EQ(j["trail"][1].size(), 10u);
  EXPECT_EQ(j["trail"][1][0][0], 5.0);
  EXPECT_NEAR(j["rates"]["odometry_hz"].get<double>(), 200.0, 0.5);
  EXPECT_EQ(j["received"]["odometry"], 600);
}

TEST(ViewState, APositionOnlyPoseHasNoHeadingAndTheOdometryStaysTheNewerPicture) {
  ViewState state(twoAnchors());
  dds::PoseMessage fix;
  fix.stamp_ns = 2'000'000'000;
  fix.p_w_b = Eigen::Vector3d(3.0, 4.0, 1.3);
  fix.covariance = dds::Mat6::Identity() * 0.04;
  fix.covariance.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity() * (std::numbers::pi * std::numbers::pi / 3.0);
  state.onPose(fix);
  json j = json::parse(state.json());
  EXPECT_EQ(j["pose"]["source"], "pose");
  EXPECT_EQ(j["pose"]["position_only"], true);
  EXPECT_TRUE(j["pose"]["yaw_deg"].is_null());
  EXPECT_TRUE(j["pose"]["sigma_yaw_deg"].is_null());
  // Tracking: odometry at IMU rate; a smoothed pose just behind it does not replace it.
  state.onOdometry(odometryAt(3'000'000'000, 3.2, 4.1, 0.0));
  dds::PoseMessage smoothed = fix;
  smoothed.stamp_ns = 2'990'000'000;
  smoothed.covariance = dds::Mat6::Identity() * 0.01;
  state.onPose(smoothed);
  j = json::parse(state.json());
  EXPECT_EQ(j["pose"]["source"], "odometry");
  EXPECT_EQ(j["pose"]["x"], 3.2);
  EXPECT_EQ(j["received"]["pose"], 2);
}

TEST(ViewState, TheStatusAndTextsThatAreNotUtf8) {
  ViewState state(twoAnchors());
  dds::StatusMessage m;
  m.state_name = "degraded";
  m.stamp_ns = 5'000'000'000;
  m.status.range_samples = 40;
  m.status.rejected_ranges = 7;
  const std::string reason = "source 0 silent \xff\xfe for 1.2 s";  // bytes off the wire
  std::copy(reason.begin(), reason.end(), m.status.reason.begin());
  state.onStatus(m);
  json j = json::parse(state.json());  // still valid JSON
  EXPECT_EQ(j["status"]["state"], "degraded");
  EXPECT_EQ(j["status"]["rejected_ranges"], 7);
  EXPECT_NE(j["status"]["reason"].get<std::string>().find("for 1.2 s"), std::string::npos);
}

TEST(ViewState, EachAnchorKeepsItsNewestJudgedRange) {
  ViewState state(twoAnchors());
  dds::RangesMessage first;
  first.stamp_ns = 1'000'000'000;
  first.ranges = {{0, 4.0, 3.9, 0.1, 0.9, false}, {3, 9.0, 7.0, 2.0, 0.01, true}};
  state.onRanges(first);
  dds::RangesMessage second;
  second.stamp_ns = 1'025'000'000;
  second.ranges = {{0, 4.1, 4.08, 0.02, 0.99, false, 37'500'000}};
  state.onRanges(second);
  json j = json::parse(state.json());
  ASSERT_EQ(j["ranges"].size(), 2u);
  EXPECT_EQ(j["ranges"][0]["anchor_id"], 0);
  EXPECT_EQ(j["ranges"][0]["range_m"], 4.1) << "the newest";
  EXPECT_EQ(j["ranges"][0]["residual_m"], 0.02);
  EXPECT_EQ(j["ranges"][0]["nlos"], false);
  EXPECT_EQ(j["ranges"][0]["t_offset_ms"], 37.5) << "the range's time after its state's stamp";
  EXPECT_EQ(j["ranges"][1]["anchor_id"], 3);
  EXPECT_EQ(j["ranges"][1]["nlos"], true);
  EXPECT_EQ(j["ranges"][1]["weight"], 0.01);
  EXPECT_GE(j["ranges"][1]["age_s"].get<double>(), 0.0);
  EXPECT_FALSE(j["age_s"]["ranges"].is_null());
}

TEST(ViewState, WaitNewerReturnsOnAMessageOrAtTheTimeout) {
  ViewState state(twoAnchors());
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(state.waitNewer(0, 50ms), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 50ms);
  std::thread feeder([&] {
    std::this_thread::sleep_for(20ms);
    state.onOdometry(odometryAt(1'000, 1.0, 1.0, 0.0));
  });
  EXPECT_EQ(state.waitNewer(0, 10s), 1u);
  feeder.join();
}

TEST(ViewServer, ServesThePageTheStateAndPushesChangesAsEvents) {
  ViewState state(twoAnchors());
  ViewServer server(state, std::string(viewPageHtml()));
  const int port = server.bind("127.0.0.1", 0);
  ASSERT_GT(port, 0);
  std::thread http([&] { server.run(); });
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(10, 0);

  const auto page = client.Get("/");
  ASSERT_TRUE(page) << httplib::to_string(page.error());
  EXPECT_EQ(page->status, 200);
  EXPECT_NE(page->get_header_value("Content-Type").find("text/html"), std::string::npos);
  EXPECT_NE(page->body.find("new EventSource(\"events\")"), std::string::npos);
  EXPECT_NE(page->body.find("<canvas id=\"plan\""), std::string::npos);

  state.onOdometry(odometryAt(1'000'000'000, 2.5, 3.5, 0.0));
  const auto snapshot = client.Get("/state");
  ASSERT_TRUE(snapshot);
  EXPECT_EQ(json::parse(snapshot->body)["pose"]["x"], 2.5);

  // Server-sent events: the current picture at once, then one per change.
  std::string stream;
  std::thread mover([&] {
    std::this_thread::sleep_for(300ms);
    state.onOdometry(odometryAt(1'100'000'000, 2.75, 3.5, 0.0));
  });
  httplib::Client events_client("127.0.0.1", port);
  events_client.set_read_timeout(10, 0);
  const auto events = events_client.Get("/events", [&](const char* data, std::size_t length) {
    stream.append(data, length);
    return stream.find("\"x\":2.75") == std::string::npos;  // stop reading after the moved pose
  });
  mover.join();
  EXPECT_EQ(stream.rfind("data: {", 0), 0u) << stream.substr(0, 80);
  EXPECT_NE(stream.find("\"x\":2.5"), std::string::npos);
  EXPECT_NE(stream.find("\"x\":2.75"), std::string::npos);
  EXPECT_NE(stream.find("\n\ndata: {"), std::string::npos) << "two events, each ended by a blank line";

  server.stop();
  http.join();
}

TEST(ViewServer, AnOpenPageGetsThePictureAtOnceBeforeAnyMessage) {
  ViewState state(twoAnchors());  // no service yet: the floor plan all the same
  ViewServer server(state, "<html></html>");
  const int port = server.bind("127.0.0.1", 0);
  std::thread http([&] { server.run(); });
  const ServerThread joined{server, http};
  httplib::Client client("127.0.0.1", port);
  client.set_read_timeout(10, 0);
  std::string stream;
  client.Get("/events", [&](const char* data, std::size_t length) {
    stream.append(data, length);
    return stream.find("\n\n") == std::string::npos;  // one event
  });
  ASSERT_EQ(stream.rfind("data: ", 0), 0u) << stream;
  json first = json::parse(stream.substr(6, stream.find("\n\n") - 6));
  EXPECT_EQ(first["anchors"].size(), 2u);
  EXPECT_TRUE(first["pose"].is_null());
  EXPECT_TRUE(first["age_s"]["status"].is_null()) << "nothing received yet";
}

TEST(ViewServer, AStopBeforeTheServerRunsEndsItAtOnce) {
  ViewState state(twoAnchors());
  ViewServer server(state, "<html></html>");
  server.bind("127.0.0.1", 0);
  server.stop();  // Ctrl-C right after the URL was printed
  auto ran = std::async(std::launch::async, [&] { server.run(); });
  EXPECT_EQ(ran.wait_for(5s), std::future_status::ready) << "run() after stop() must not serve for ever";
  // And the other order: stop() while run() is just starting.
  ViewServer second(state, "<html></html>");
  second.bind("127.0.0.1", 0);
  auto running = std::async(std::launch::async, [&] { second.run(); });
  second.stop();
  EXPECT_EQ(running.wait_for(5s), std::future_status::ready);
}

TEST(ViewServer, ABusyPortIsAnErrorNamingTheAddress) {
  ViewState state(twoAnchors());
  ViewServer first(state, "<html></html>");
  const int port = first.bind("127.0.0.1", 0);
  ViewServer second(state, "<html></html>");
  try {
    second.bind("127.0.0.1", port);
    FAIL() << "bound a busy port";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:" + std::to_string(port)), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rilo::tool
