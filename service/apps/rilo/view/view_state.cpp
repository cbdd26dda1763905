#include "view_state.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include <nlohmann/json.hpp>

#include "dds/conversions.h"

namespace rilo::tool {
namespace {

using Json = nlohmann::ordered_json;

constexpr double kDeg = 180.0 / std::numbers::pi;

/// Orientation variance above which a pose carries no heading: the
/// position-only fix says "unknown" with pi^2/3 (an angle uniform over a turn).
constexpr double kUnknownOrientationVariance = 3.0;

double round3(double v) { return std::round(v * 1e3) / 1e3; }

}  // namespace

void ViewState::Rate::add(std::int64_t stamp_ns) {
  ++received;
  arrived = std::chrono::steady_clock::now();
  if (!stamps_ns.empty() && stamp_ns <= stamps_ns.back()) stamps_ns.clear();  // publisher restarted
  stamps_ns.push_back(stamp_ns);
  while (stamps_ns.size() > 2 && stamps_ns.back() - stamps_ns.front() > 1'000'000'000) stamps_ns.pop_front();
}

double ViewState::Rate::hz() const {
  if (stamps_ns.size() < 2) return 0.0;
  return static_cast<double>(stamps_ns.size() - 1) / (static_cast<double>(stamps_ns.back() - stamps_ns.front()) * 1e-9);
}

double ViewState::Rate::ageS(std::chrono::steady_clock::time_point now) const {
  return std::chrono::duration<double>(now - arrived).count();
}

ViewState::ViewState(std::vector<Anchor> anchors) : anchors_(std::move(anchors)) {}

ViewState::PoseView ViewState::PoseView::of(const char* source, const auto& m, const dds::Mat6& covariance) {
  PoseView p;
  p.valid = true;
  p.source = source;
  p.stamp_ns = m.stamp_ns;
  p.p_w_b = m.p_w_b;
  p.q_w_b = m.q_w_b;
  p.covariance = covariance;
  return p;
}

void ViewState::onOdometry(const dds::OdometryMessage& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  odometry_.add(m.stamp_ns);
  PoseView p = PoseView::of("odometry", m, m.pose_covariance);
  p.v_b = m.v_b;
  takePose(p);
  changed();
}

void ViewState::onPose(const dds::PoseMessage& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  poses_.add(m.stamp_ns);
  PoseView p = PoseView::of("pose", m, m.covariance);
  p.position_only = m.covariance.bottomRightCorner<3, 3>().diagonal().maxCoeff() > kUnknownOrientationVariance;
  // The odometry (IMU rate, extrapolated from these) is the newer picture
  // while it flows; a smoothed pose only replaces a stale one.
  if (!pose_.valid || pose_.source != std::string_view("odometry") || m.stamp_ns > pose_.stamp_ns + 500'000'000) {
    takePose(p);
  }
  changed();
}

void ViewState::onStatus(const dds::StatusMessage& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  statuses_.add(m.stamp_ns);
  status_ = m;
  have_status_ = true;
  changed();
}

void ViewState::onRanges(const dds::RangesMessage& m) {
  std::lock_guard<std::mutex> lock(mutex_);
  ranges_.add(m.stamp_ns);
  for (const dds::RangeReading& r : m.ranges) newest_range_[r.anchor_id] = {r, ranges_.arrived};
  changed();
}

void ViewState::takePose(const PoseView& pose) {
  if (pose_.valid && pose.stamp_ns < pose_.stamp_ns - 2'000'000'000) trail_.clear();  // the service restarted
  pose_ = pose;
  if (trail_.empty() || pose.stamp_ns >= trail_last_ns_ + kTrailStepNs) {
    trail_.push_back({pose.p_w_b, trail_.empty() || pose.stamp_ns > trail_last_ns_ + kTrailBreakNs});
    trail_last_ns_ = pose.stamp_ns;
    while (trail_.size() > kTrailPoints) trail_.pop_front();
  }
}

void ViewState::changed() {
  ++version_;
  changed_cv_.notify_all();
}

std::uint64_t ViewState::version() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return version_;
}

std::uint64_t ViewState::waitNewer(std::uint64_t seen, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> lock(mutex_);
  changed_cv_.wait_for(lock, timeout, [&] { return version_ > seen; });
  return version_;
}

std::string ViewState::json() const {
  Json j;
  Json anchors = Json::array();
  for (const Anchor& a : anchors_) {
    anchors.push_back(Json{{"id", a.id},
                           {"kind", std::string(toString(a.kind))},
                           {"x", round3(a.p_w_anchor.x())},
                           {"y", round3(a.p_w_anchor.y())},
                           {"z", round3(a.p_w_anchor.z())}});
  }
  j["anchors"] = std::move(anchors);

  std::lock_guard<std::mutex> lock(mutex_);
  j["version"] = version_;
  if (pose_.valid) {
    const Eigen::Quaterniond q = pose_.q_w_b.normalized();
    // ZYX angles (REP-103), degrees; the covariance's position block for the ellipse.
    const double yaw = std::atan2(2.0 * (q.w() * q.z() + q.x() * q.y()), 1.0 - 2.0 * (q.y() * q.y() + q.z() * q.z()));
    const dds::Mat6& c = pose_.covariance;
    Json pose{{"source", pose_.source},
              {"stamp_ns", pose_.stamp_ns},
              {"x", round3(pose_.p_w_b.x())},
              {"y", round3(pose_.p_w_b.y())},
              {"z", round3(pose_.p_w_b.z())},
              {"position_only", pose_.position_only},
              {"yaw_deg", pose_.position_only ? Json(nullptr) : Json(std::round(yaw * kDeg * 10.0) / 10.0)},
              {"cov_xx", c(0, 0)},
              {"cov_xy", c(0, 1)},
              {"cov_yy", c(1, 1)},
              {"sigma_z", std::sqrt(std::max(0.0, c(2, 2)))},
              {"sigma_yaw_deg", pose_.position_only ? Json(nullptr) : Json(std::sqrt(std::max(0.0, c(5, 5))) * kDeg)},
              {"speed_m_s", round3(pose_.v_b.norm())}};
    j["pose"] = std::move(pose);
  } else {
    j["pose"] = nullptr;
  }
  // Segments of [x, y] points: a new one after each pause in the poses.
  Json trail = Json::array();
  for (const TrailPoint& t : trail_) {
    if (t.starts_segment || trail.empty()) trail.push_back(Json::array());
    trail.back().push_back({round3(t.p_w_b.x()), round3(t.p_w_b.y())});
  }
  j["trail"] = std::move(trail);
  j["rates"] = Json{{"odometry_hz", std::round(odometry_.hz() * 10.0) / 10.0},
                    {"pose_hz", std::round(poses_.hz() * 10.0) / 10.0},
                    {"status_hz", std::round(statuses_.hz() * 10.0) / 10.0}};
  j["received"] = Json{{"odometry", odometry_.received}, {"pose", poses_.received}, {"status", statuses_.received}};
  const auto now = std::chrono::steady_clock::now();
  const auto age = [&](const Rate& r) { return r.received > 0 ? Json(std::round(r.ageS(now) * 10.0) / 10.0) : Json(nullptr); };
  j["age_s"] = Json{{"odometry", age(odometry_)}, {"pose", age(poses_)}, {"status", age(statuses_)}, {"ranges", age(ranges_)}};
  Json ranges = Json::array();
  for (const auto& [id, a] : newest_range_) {
    const dds::RangeReading& r = a.reading;
    ranges.push_back(Json{{"anchor_id", id},
                          {"range_m", round3(r.range_m)},
                          {"predicted_m", round3(r.predicted_m)},
                          {"residual_m", round3(r.residual_m)},
                          {"weight", std::round(r.weight * 1e3) / 1e3},
                          {"nlos", r.nlos},
                          {"t_offset_ms", std::round(r.t_offset_ns * 1e-5) / 10.0},
                          {"age_s", std::round(std::chrono::duration<double>(now - a.arrived).count() * 10.0) / 10.0}});
  }
  j["ranges"] = std::move(ranges);
  if (have_status_) {
    const ServiceStatus& s = status_.status;
    j["status"] = Json{{"state", status_.state_name},
                       {"reason", std::string(s.reason.data())},
                       {"last_fault", std::string(s.last_fault.data())},
                       {"stamp_ns", status_.stamp_ns},
                       {"imu_samples", s.imu_samples},
                       {"range_samples", s.range_samples},
                       {"rejected_ranges", s.rejected_ranges},
                       {"tdoa_samples", s.tdoa_samples},
                       {"ultrasonic_samples", s.ultrasonic_samples},
                       {"published_odometry", s.published_odometry},
                       {"reinitializations", s.reinitializations},
                       {"sensor_faults", s.sensor_faults},
                       {"queue_overflows", s.queue_overflows},
                       {"late_updates", s.late_updates},
                       {"imu_gaps", s.imu_gaps},
                       {"ranging_gaps", s.ranging_gaps},
                       {"mean_update_ms", s.mean_update_ms},
                       {"p99_update_ms", s.p99_update_ms},
                       {"max_update_ms", s.max_update_ms},
                       {"odometry_latency_ms", s.odometry_latency_ms},
                       {"pose_latency_ms", s.pose_latency_ms}};
  } else {
    j["status"] = nullptr;
  }
  // Texts off the wire are not trusted to be UTF-8.
  return j.dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace rilo::tool
