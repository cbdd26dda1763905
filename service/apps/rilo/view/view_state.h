#pragma once
// What `rilo view` shows, gathered from the DDS topics as they arrive: the
// anchors (from the configuration the service runs), the newest pose with its
// covariance and heading, a trail, the status, and per-topic rates. Any
// thread may feed it or read it; json() is the one picture the page draws
// (view_page.html), and waitNewer() lets the server push it on change.
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "dds/messages.h"
#include "hal/recording/recording.h"

namespace rilo::tool {

class ViewState {
 public:
  /// Trail: a position every kTrailStepNs of stamp time, the last kTrailPoints;
  /// a pause longer than kTrailBreakNs (nothing published) starts a new segment.
  static constexpr std::int64_t kTrailStepNs = 100'000'000;
  static constexpr std::int64_t kTrailBreakNs = 1'000'000'000;
  static constexpr std::size_t kTrailPoints = 600;

  explicit ViewState(std::vector<Anchor> anchors);

  void onOdometry(const dds::OdometryMessage& m);
  void onPose(const dds::PoseMessage& m);
  void onStatus(const dds::StatusMessage& m);
  void onRanges(const dds::RangesMessage& m);

  /// Everything the page draws, as one JSON object:
  ///   anchors  [{id, kind, x, y, z}]            from the configuration (m, world)
  ///   version  grows with every message
  ///   pose     {source, stamp_ns, x, y, z, position_only, yaw_deg (null without a heading),
  ///             cov_xx, cov_xy, cov_yy (m^2), sigma_z (m), sigma_yaw_deg, speed_m_s} or null
  ///   trail    [[[x, y], ...], ...]             segments, a new one after each pause
  ///   rates    {odometry_hz, pose_hz, status_hz}, received {odometry, pose, status}
  ///   age_s    {odometry, pose, status, ranges}: seconds since the newest was taken (null: none yet)
  ///   ranges   [{anchor_id, range_m, predicted_m, residual_m, weight, nlos, age_s}]: each
  ///            anchor's newest judged range (the estimator's verdict), by anchor id
  ///   status   {state, reason, last_fault, counters, update and latency figures} or null
  std::string json() const;
  /// Grows with every message taken.
  std::uint64_t version() const;
  /// Blocks until version() > seen or `timeout` passes; returns version().
  std::uint64_t waitNewer(std::uint64_t seen, std::chrono::milliseconds timeout) const;

 private:
  /// Messages per second of one topic, from its stamps over the last second.
  struct Rate {
    std::deque<std::int64_t> stamps_ns;
    std::uint64_t received = 0;
    std::chrono::steady_clock::time_point arrived;  ///< when the newest one was taken (this machine's clock)
    void add(std::int64_t stamp_ns);
    double hz() const;
    /// Seconds since the newest one was taken, or null before the first.
    double ageS(std::chrono::steady_clock::time_point now) const;
  };
  struct PoseView {
    bool valid = false;
    bool position_only = false;  ///< orientation unknown (the initializing fix)
    const char* source = "";     ///< "odometry" or "pose"
    std::int64_t stamp_ns = 0;
    Eigen::Vector3d p_w_b = Eigen::Vector3d::Zero();
    Eigen::Quaterniond q_w_b = Eigen::Quaterniond::Identity();
    dds::Mat6 covariance = dds::Mat6::Zero();
    Eigen::Vector3d v_b = Eigen::Vector3d::Zero();
    /// The stamp and pose of an odometry or pose message.
    static PoseView of(const char* source, const auto& message, const dds::Mat6& covariance);
  };

  void takePose(const PoseView& pose);  // under the mutex
  void changed();                       // under the mutex

  std::vector<Anchor> anchors_;
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_cv_;
  std::uint64_t version_ = 0;
  PoseView pose_;
  struct TrailPoint {
    Eigen::Vector3d p_w_b;
    bool starts_segment;
  };
  std::deque<TrailPoint> trail_;
  std::int64_t trail_last_ns_ = 0;
  Rate odometry_, poses_, statuses_, ranges_;
  struct AnchorRange {
    dds::RangeReading reading;
    std::chrono::steady_clock::time_point arrived;
  };
  std::map<std::uint32_t, AnchorRange> newest_range_;  ///< by anchor id
  bool have_status_ = false;
  dds::StatusMessage status_;
};

}  // namespace rilo::tool
