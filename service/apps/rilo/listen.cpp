#include "listen.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <deque>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "dds/conversions.h"
#include "dds/participant.h"
#include "dds/stamp_clock.h"
#include "dds/subscriber.h"
#include "unsigned_option.h"

namespace rilo::tool {
namespace {

volatile std::sig_atomic_t g_stop = 0;
extern "C" void onStopSignal(int) { g_stop = 1; }

constexpr int kExitSetupError = 1;
constexpr int kExitTimeout = 2;

/// Rate of one topic from its stamps over the last second.
class RateMeter {
 public:
  double add(std::int64_t stamp_ns) {
    if (!stamps_.empty() && stamp_ns <= stamps_.back()) stamps_.clear();  // publisher restarted or reordered
    stamps_.push_back(stamp_ns);
    while (stamps_.size() > 2 && stamps_.back() - stamps_.front() > kWindowNs) stamps_.pop_front();
    if (stamps_.size() < 2) return 0.0;
    const double span_s = static_cast<double>(stamps_.back() - stamps_.front()) * 1e-9;
    return static_cast<double>(stamps_.size() - 1) / span_s;
  }

 private:
  static constexpr std::int64_t kWindowNs = 1'000'000'000;
  std::deque<std::int64_t> stamps_;
};

struct Rpy {
  double roll_deg, pitch_deg, yaw_deg;
};

/// ZYX (yaw, pitch, roll) angles of the body in the world, REP-103.
Rpy rpyOf(const Eigen::Quaterniond& q_in) {
  const Eigen::Quaterniond q = q_in.normalized();
  const double sinp = std::clamp(2.0 * (q.w() * q.y() - q.z() * q.x()), -1.0, 1.0);
  constexpr double kDeg = 180.0 / M_PI;
  return {std::atan2(2.0 * (q.w() * q.x() + q.y() * q.z()), 1.0 - 2.0 * (q.x() * q.x() + q.y() * q.y())) * kDeg,
          std::asin(sinp) * kDeg,
          std::atan2(2.0 * (q.w() * q.z() + q.x() * q.y()), 1.0 - 2.0 * (q.y() * q.y() + q.z() * q.z())) * kDeg};
}

Eigen::Vector3d sigmas(const dds::Mat6& covariance) {
  return covariance.diagonal().head<3>().cwiseMax(0.0).cwiseSqrt();
}

double stampSeconds(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

// --- JSON, one object per line (nlohmann-json; NaN and inf dump as null) -----

using Json = nlohmann::ordered_json;

/// {"topic": topic, ...}: the caller adds the fields in print order.
Json jsonLine(const char* topic) { return Json{{"topic", topic}}; }

template <class Vector>
Json jsonArray(const Vector& v) {
  Json out = Json::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(v(i));
  return out;
}

/// Row-major, as on the wire.
Json jsonMatrix(const dds::Mat6& m) {
  Json out = Json::array();
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) out.push_back(m(r, c));
  }
  return out;
}

void printJson(const Json& line) {
  // Frame ids and fault texts come off the wire: bad UTF-8 becomes U+FFFD.
  std::fputs((line.dump(-1, ' ', false, Json::error_handler_t::replace) + "\n").c_str(), stdout);
  std::fflush(stdout);
}

Eigen::Vector4d xyzw(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }

// --- printing ----------------------------------------------------------------

struct TopicStats {
  RateMeter rate;
  std::uint64_t received = 0;
};

void printOdometry(const dds::OdometryMessage& m, double rate_hz, double latency_ms, bool json) {
  if (json) {
    Json j = jsonLine("odometry");
    j["stamp_ns"] = m.stamp_ns;
    j["frame_id"] = m.frame_id;
    j["child_frame_id"] = m.child_frame_id;
    j["position"] = jsonArray(m.p_w_b);
    j["orientation_xyzw"] = jsonArray(xyzw(m.q_w_b));
    j["linear_velocity_body"] = jsonArray(m.v_b);
    j["angular_velocity_body"] = jsonArray(m.omega_b);
    j["pose_covariance"] = jsonMatrix(m.pose_covariance);
    j["twist_covariance"] = jsonMatrix(m.twist_covariance);
    j["rate_hz"] = rate_hz;
    j["latency_ms"] = latency_ms;
    printJson(j);
    return;
  }
  const Rpy rpy = rpyOf(m.q_w_b);
  const Eigen::Vector3d s = sigmas(m.pose_covariance);
  std::printf(
      "odometry %14.6f  p [%8.3f %8.3f %8.3f] m  rpy [%7.2f %7.2f %7.2f] deg  v_b [%6.2f %6.2f %6.2f] m/s  "
      "sigma_p [%.3f %.3f %.3f] m  %6.1f Hz  latency %7.2f ms\n",
      stampSeconds(m.stamp_ns), m.p_w_b.x(), m.p_w_b.y(), m.p_w_b.z(), rpy.roll_deg, rpy.pitch_deg, rpy.yaw_deg,
      m.v_b.x(), m.v_b.y(), m.v_b.z(), s.x(), s.y(), s.z(), rate_hz, latency_ms);
  std::fflush(stdout);
}

void printPose(const dds::PoseMessage& m, double rate_hz, double latency_ms, bool json) {
  if (json) {
    Json j = jsonLine("pose");
    j["stamp_ns"] = m.stamp_ns;
    j["frame_id"] = m.frame_id;
    j["position"] = jsonArray(m.p_w_b);
    j["orientation_xyzw"] = jsonArray(xyzw(m.q_w_b));
    j["covariance"] = jsonMatrix(m.covariance);
    j["rate_hz"] = rate_hz;
    j["latency_ms"] = latency_ms;
    printJson(j);
    return;
  }
  const Rpy rpy = rpyOf(m.q_w_b);
  const Eigen::Vector3d s = sigmas(m.covariance);
  std::printf(
      "pose     %14.6f  p [%8.3f %8.3f %8.3f] m  rpy [%7.2f %7.2f %7.2f] deg  sigma_p [%.3f %.3f %.3f] m  "
      "%6.1f Hz  latency %7.2f ms\n",
      stampSeconds(m.stamp_ns), m.p_w_b.x(), m.p_w_b.y(), m.p_w_b.z(), rpy.roll_deg, rpy.pitch_deg, rpy.yaw_deg,
      s.x(), s.y(), s.z(), rate_hz, latency_ms);
  std::fflush(stdout);
}

void printStatus(const dds::StatusMessage& m, double rate_hz, double latency_ms, bool json) {
  const ServiceStatus& s = m.status;
  std::string fault(s.last_fault.data());
  std::string reason(s.reason.data());
  if (!json) {  // one line per sample
    auto printable = [](std::string& text) {
      std::replace_if(text.begin(), text.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; }, ' ');
    };
    printable(fault);
    printable(reason);
  }
  if (json) {
    Json j = jsonLine("status");
    j["stamp_ns"] = m.stamp_ns;
    j["state"] = static_cast<std::uint64_t>(s.state);
    j["state_name"] = m.state_name;
    j["imu_samples"] = s.imu_samples;
    j["range_samples"] = s.range_samples;
    j["tdoa_samples"] = s.tdoa_samples;
    j["ultrasonic_samples"] = s.ultrasonic_samples;
    j["queue_overflows"] = s.queue_overflows;
    j["late_updates"] = s.late_updates;
    j["sensor_faults"] = s.sensor_faults;
    j["sensor_silences"] = s.sensor_silences;
    j["reinitializations"] = s.reinitializations;
    j["rejected_ranges"] = s.rejected_ranges;
    j["deep_nlos_tdoa_rows"] = s.deep_nlos_tdoa_rows;
    j["published_odometry"] = s.published_odometry;
    j["non_finite_samples"] = s.non_finite_samples;
    j["duplicate_samples"] = s.duplicate_samples;
    j["out_of_order_samples"] = s.out_of_order_samples;
    j["imu_gaps"] = s.imu_gaps;
    j["ranging_gaps"] = s.ranging_gaps;
    j["out_of_bounds_samples"] = s.out_of_bounds_samples;
    j["beyond_full_scale_samples"] = s.beyond_full_scale_samples;
    j["far_future_samples"] = s.far_future_samples;
    j["time_jumps"] = s.time_jumps;
    j["last_update_ms"] = s.last_update_ms;
    j["mean_update_ms"] = s.mean_update_ms;
    j["max_update_ms"] = s.max_update_ms;
    j["p99_update_ms"] = s.p99_update_ms;
    j["estimator_queue_high_water"] = s.estimator_queue_high_water;
    j["publisher_queue_high_water"] = s.publisher_queue_high_water;
    j["last_cliques_reeliminated"] = s.last_cliques_reeliminated;
    j["last_relinearized"] = s.last_relinearized;
    j["last_lambda"] = s.last_lambda;
    j["odometry_latency_ms"] = s.odometry_latency_ms;
    j["pose_latency_ms"] = s.pose_latency_ms;
    j["monotonic_ns"] = s.t_ns;
    j["last_fault"] = fault;
    j["reason"] = reason;
    j["rate_hz"] = rate_hz;
    j["latency_ms"] = latency_ms;
    printJson(j);
    return;
  }
  char tdoa[96] = "";  // the IMU-Ultrasonic-UWB paper's system only
  if (s.tdoa_samples > 0 || s.ultrasonic_samples > 0) {
    std::snprintf(tdoa, sizeof tdoa, "  tdoa %llu (deep NLOS %llu)  ultrasonic %llu",
                  static_cast<unsigned long long>(s.tdoa_samples), static_cast<unsigned long long>(s.deep_nlos_tdoa_rows),
                  static_cast<unsigned long long>(s.ultrasonic_samples));
  }
  char screen[160] = "";  // only when the estimator's screen dropped something
  if (s.out_of_bounds_samples + s.beyond_full_scale_samples + s.far_future_samples + s.time_jumps > 0) {
    std::snprintf(screen, sizeof screen, "  screened %llu/%llu/%llu (out-of-bounds/beyond-full-scale/far-future), %llu time jumps",
                  static_cast<unsigned long long>(s.out_of_bounds_samples),
                  static_cast<unsigned long long>(s.beyond_full_scale_samples),
                  static_cast<unsigned long long>(s.far_future_samples), static_cast<unsigned long long>(s.time_jumps));
  }
  std::printf(
      "status   %14.6f  %-12s imu %llu  ranges %llu (rejected %llu)%s  overflows %llu  late %llu  faults %llu  "
      "silences %llu  reinit %llu  dropped %llu/%llu/%llu (non-finite/duplicate/out-of-order)%s  gaps %llu/%llu "
      "(imu/ranging)  update %.2f ms (mean %.2f, p99 %.2f, max %.2f)  queues %u/%u (high water)  odometry latency %.2f ms  pose latency "
      "%.2f ms  %5.1f Hz  latency %7.2f ms%s%s%s%s%s%s\n",
      stampSeconds(m.stamp_ns), m.state_name.c_str(), static_cast<unsigned long long>(s.imu_samples),
      static_cast<unsigned long long>(s.range_samples), static_cast<unsigned long long>(s.rejected_ranges), tdoa,
      static_cast<unsigned long long>(s.queue_overflows), static_cast<unsigned long long>(s.late_updates),
      static_cast<unsigned long long>(s.sensor_faults), static_cast<unsigned long long>(s.sensor_silences),
      static_cast<unsigned long long>(s.reinitializations), static_cast<unsigned long long>(s.non_finite_samples),
      static_cast<unsigned long long>(s.duplicate_samples), static_cast<unsigned long long>(s.out_of_order_samples), screen,
      static_cast<unsigned long long>(s.imu_gaps), static_cast<unsigned long long>(s.ranging_gaps), s.last_update_ms,
      s.mean_update_ms, s.p99_update_ms, s.max_update_ms, s.estimator_queue_high_water, s.publisher_queue_high_water,
      s.odometry_latency_ms, s.pose_latency_ms, rate_hz, latency_ms,
      reason.empty() ? "" : "  reason \"", reason.c_str(), reason.empty() ? "" : "\"",
      fault.empty() ? "" : "  fault \"", fault.c_str(), fault.empty() ? "" : "\"");
  std::fflush(stdout);
}

void printTransform(const dds::TransformMessage& m, double rate_hz, double latency_ms, bool json) {
  if (json) {
    Json j = jsonLine("tf");
    j["stamp_ns"] = m.stamp_ns;
    j["frame_id"] = m.frame_id;
    j["child_frame_id"] = m.child_frame_id;
    j["translation"] = jsonArray(m.translation);
    j["rotation_xyzw"] = jsonArray(xyzw(m.rotation));
    j["rate_hz"] = rate_hz;
    j["latency_ms"] = latency_ms;
    printJson(j);
    return;
  }
  const Rpy rpy = rpyOf(m.rotation);
  std::printf("tf       %14.6f  %s -> %s  t [%8.3f %8.3f %8.3f] m  rpy [%7.2f %7.2f %7.2f] deg  %6.1f Hz  latency %7.2f ms\n",
              stampSeconds(m.stamp_ns), m.frame_id.c_str(), m.child_frame_id.c_str(), m.translation.x(),
              m.translation.y(), m.translation.z(), rpy.roll_deg, rpy.pitch_deg, rpy.yaw_deg, rate_hz, latency_ms);
  std::fflush(stdout);
}

/// now - stamp (ms) on the stamps' own clock: system time (the service's
/// dds.stamp_clock: system, the default) or CLOCK_MONOTONIC (monotonic). The
/// two clocks are decades apart, so the one nearer the stamp is its clock.
double latencyMs(std::int64_t stamp_ns) {
  const std::int64_t system_ns = dds::clockNowNs(CLOCK_REALTIME);
  const std::int64_t monotonic_ns = dds::clockNowNs(CLOCK_MONOTONIC);
  const std::int64_t now_ns =
      std::llabs(system_ns - stamp_ns) <= std::llabs(monotonic_ns - stamp_ns) ? system_ns : monotonic_ns;
  return static_cast<double>(now_ns - stamp_ns) * 1e-6;
}

}  // namespace

int runListen(const ListenOptions& o) {
  dds::SubscriberOptions so;
  so.topics.odometry = o.odometry_topic;
  so.topics.pose = o.pose_topic;
  so.topics.status = o.status_topic;
  so.topics.tf = o.tf_topic;
  so.odometry = o.topic == "all" || o.topic == "odometry";
  so.pose = o.topic == "all" || o.topic == "pose";
  so.status = o.topic == "all" || o.topic == "status";
  so.tf = o.topic == "tf";
  if (!so.odometry && !so.pose && !so.status && !so.tf) {
    throw std::invalid_argument("--topic must be odometry, pose, status, tf or all, got '" + o.topic + "'");
  }
  if (!(o.timeout_s >= 0.0)) throw std::invalid_argument("--timeout must be >= 0");

  const dds::Participant participant(
      dds::ParticipantOptions{o.domain, o.loopback ? dds::loopbackConfigXml() : std::string()});
  dds::Subscriber subscriber(participant, so);
  if (!o.json) {
    std::string topics;
    for (const auto& [on, name] : {std::pair{so.odometry, &so.topics.odometry}, std::pair{so.pose, &so.topics.pose},
                                   std::pair{so.status, &so.topics.status}, std::pair{so.tf, &so.topics.tf}}) {
      if (on) topics += (topics.empty() ? "" : " ") + *name;
    }
    spdlog::info("domain {}, {} (latency = now - stamp on the stamps' clock)", o.domain, topics);
  }

  g_stop = 0;
  std::signal(SIGINT, onStopSignal);
  std::signal(SIGTERM, onStopSignal);

  TopicStats odometry_stats, pose_stats, status_stats, tf_stats;
  std::vector<dds::OdometryMessage> odometry;
  std::vector<dds::PoseMessage> poses;
  std::vector<dds::StatusMessage> statuses;
  std::vector<dds::TfMessage> tf;
  std::uint64_t received = 0;
  const auto timeout = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(o.timeout_s));
  auto last_arrival = std::chrono::steady_clock::now();
  const auto done = [&] { return o.count > 0 && received >= o.count; };

  while (g_stop == 0) {
    auto wait = std::chrono::nanoseconds(std::chrono::milliseconds(100));  // bounded so signals are seen
    if (o.timeout_s > 0.0) {
      const auto left = timeout - (std::chrono::steady_clock::now() - last_arrival);
      if (left <= std::chrono::nanoseconds::zero()) {
        spdlog::error("nothing received for {:.1f} s on domain {}", o.timeout_s, o.domain);
        return kExitTimeout;
      }
      wait = std::min(wait, std::chrono::duration_cast<std::chrono::nanoseconds>(left));
    }
    if (!subscriber.waitForData(wait)) continue;

    odometry.clear();
    poses.clear();
    statuses.clear();
    tf.clear();
    subscriber.takeOdometry(odometry);
    subscriber.takePose(poses);
    subscriber.takeStatus(statuses);
    subscriber.takeTf(tf);
    if (!odometry.empty() || !poses.empty() || !statuses.empty() || !tf.empty()) {
      last_arrival = std::chrono::steady_clock::now();
    }
    for (const auto& m : odometry) {
      if (done()) break;
      printOdometry(m, odometry_stats.rate.add(m.stamp_ns), latencyMs(m.stamp_ns), o.json);
      ++received;
    }
    for (const auto& m : poses) {
      if (done()) break;
      printPose(m, pose_stats.rate.add(m.stamp_ns), latencyMs(m.stamp_ns), o.json);
      ++received;
    }
    for (const auto& m : statuses) {
      if (done()) break;
      printStatus(m, status_stats.rate.add(m.stamp_ns), latencyMs(m.stamp_ns), o.json);
      ++received;
    }
    for (const auto& message : tf) {
      for (const auto& m : message.transforms) {
        if (done()) break;
        printTransform(m, tf_stats.rate.add(m.stamp_ns), latencyMs(m.stamp_ns), o.json);
        ++received;
      }
    }
    if (done()) return 0;
  }
  return 0;  // interrupted
}

void addListenCommand(CLI::App& app) {
  auto options = std::make_shared<ListenOptions>();
  CLI::App* cmd = app.add_subcommand(
      "listen",
      "Subscribe to rilod's DDS topics and print poses, per-topic rate and latency (now - stamp on the stamps' "
      "clock: system time by default, CLOCK_MONOTONIC with dds.stamp_clock: monotonic)");
  cmd->add_option("--topic", options->topic, "Topic to listen to (all: odometry, pose and status)")
      ->capture_default_str()
      ->check(CLI::IsMember({"odometry", "pose", "status", "tf", "all"}));
  cmd->add_option("--count", options->count, "Stop after this many samples (0 = until Ctrl-C)")
      ->capture_default_str()
      ->check(cli::notNegative());
  cmd->add_flag("--json", options->json, "One JSON object per line");
  cmd->add_option("--domain", options->domain, "DDS domain id")
      ->capture_default_str()
      ->check(cli::notNegative())
      ->check(CLI::Range(0u, 232u));
  cmd->add_option("--timeout", options->timeout_s,
                  "Exit with code 2 when nothing arrives for this many seconds (0 = wait forever)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd->add_flag("--loopback", options->loopback,
                "Only use the loopback interface, unicast discovery (match a service started the same way)");
  cmd->add_option("--odometry-topic", options->odometry_topic, "DDS name of the odometry topic")->capture_default_str();
  cmd->add_option("--pose-topic", options->pose_topic, "DDS name of the pose topic")->capture_default_str();
  cmd->add_option("--status-topic", options->status_topic, "DDS name of the status topic")->capture_default_str();
  cmd->add_option("--tf-topic", options->tf_topic, "DDS name of the TF topic")->capture_default_str();
  cmd->callback([options] {
    int code = 0;
    try {
      code = runListen(*options);
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
      code = kExitSetupError;
    }
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool

