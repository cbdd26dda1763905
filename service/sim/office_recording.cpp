#include "sim/office_recording.h"

#include <cmath>
#include <stdexcept>

#include "sim/office_tdoa.h"
#include "sim/office_ultrasonic.h"

namespace rilo::sim {
namespace {

void checkOptions(const ScenarioRecordingOptions& o, double imu_rate_hz) {
  if (!(std::isfinite(o.truth_rate_hz) && o.truth_rate_hz > 0.0 && o.truth_rate_hz <= imu_rate_hz)) {
    throw std::invalid_argument("ScenarioRecordingOptions.truth_rate_hz must be in (0, imu rate]");
  }
}

/// Calls the progress callback when the fraction moved by at least 1%.
class Progress {
 public:
  Progress(const ScenarioRecordingOptions& o, double total) : fn_(o.progress), total_(std::max(total, 1.0)) {}
  void operator()(double done) {
    if (!fn_) return;
    const double f = std::min(1.0, done / total_);
    if (f >= last_ + 0.01 || (f >= 1.0 && last_ < 1.0)) {
      last_ = f;
      fn_(f);
    }
  }

 private:
  const std::function<void(double)>& fn_;
  double total_;
  double last_ = -1.0;
};

RecordingWriterOptions writerOptions(const ScenarioRecordingOptions& o) {
  RecordingWriterOptions w = o.writer;
  w.imu_temperature = false;
  return w;
}

void writeStatic(RecordingWriter& w, const ScenarioParams& params, const std::vector<Eigen::Vector3d>& anchors,
                 const Eigen::Vector3d& p_b_tag, const ScenarioRecordingOptions& options) {
  w.writeMeta(scenarioMeta(params, p_b_tag, options));
  w.writeAnchors(scenarioAnchors(anchors));
  w.writeTags({Tag{0, p_b_tag}});
}

}  // namespace

RecordingMeta scenarioMeta(const ScenarioParams& params, const Eigen::Vector3d& p_b_tag,
                           const ScenarioRecordingOptions& options) {
  RecordingMeta m;
  m.name = options.name;
  m.description = options.description;
  m.gravity_m_s2 = params.gravity_m_s2;
  m.imu_rate_hz = params.imu_rate_hz;
  m.gyro_noise_density = params.gyro_noise_density;
  m.accel_noise_density = params.accel_noise_density;
  m.gyro_bias_random_walk = params.gyro_bias_walk;
  m.accel_bias_random_walk = params.accel_bias_walk;
  m.uwb_lever_arm_m = p_b_tag;
  m.ultrasonic_lever_arm_m = Vec3::Zero();  // the simulated device states its whole geometry (set below with a receiver)
  m.ranging = RangingKind::kSsTwr;
  return m;
}

std::vector<Anchor> scenarioAnchors(const std::vector<Eigen::Vector3d>& p_w_anchors) {
  std::vector<Anchor> out;
  for (std::size_t i = 0; i < p_w_anchors.size(); ++i) {
    Anchor a;
    a.id = static_cast<std::uint32_t>(i);
    a.p_w_anchor = p_w_anchors[i];
    a.kind = AnchorKind::kUwb;
    out.push_back(a);
  }
  return out;
}

std::vector<std::int64_t> groundTruthTimes(std::int64_t t0_ns, double duration_s, double rate_hz) {
  const auto n = static_cast<std::int64_t>(std::floor(duration_s * rate_hz + 1e-9));
  std::vector<std::int64_t> t;
  t.reserve(static_cast<std::size_t>(n + 1));
  for (std::int64_t k = 0; k <= n; ++k) {
    t.push_back(t0_ns + static_cast<std::int64_t>(std::llround(static_cast<double>(k) / rate_hz * 1e9)));
  }
  return t;
}

GroundTruthPose groundTruthAt(const Scenario& s, std::int64_t t_ns) {
  const KinematicState st = s.truthAt(t_ns);
  GroundTruthPose g;
  g.t_ns = t_ns;
  g.p_w_b = st.T_w_b.p;
  Quat q = st.T_w_b.quaternion();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  g.q_w_b = q;
  g.v_w_b = st.v_w;
  return g;
}

void writeScenarioRecording(const Scenario& s, const std::filesystem::path& dir,
                            const ScenarioRecordingOptions& options) {
  checkOptions(options, s.params.imu_rate_hz);
  if (!s.truth) throw std::invalid_argument("writeScenarioRecording: the scenario has no truth trajectory");
  const std::vector<std::int64_t> truth_t = groundTruthTimes(s.t0_ns, s.params.duration_s, options.truth_rate_hz);
  Progress progress(options, static_cast<double>(s.imu.size() + s.ranges.size() + truth_t.size()));
  RecordingWriter w(dir, writerOptions(options));
  writeStatic(w, s.params, s.p_w_anchors, s.p_b_tag, options);
  double done = 0.0;
  for (const ImuSample& m : s.imu) {
    w.write(m);
    progress(++done);
  }
  for (const RangeSample& r : s.ranges) {
    w.write(r);
    progress(++done);
  }
  for (std::int64_t t : truth_t) {
    w.write(groundTruthAt(s, t));
    progress(++done);
  }
  w.close();
  progress(done);
}

OfficeStats writeOfficeRecording(const OfficeScenarioParams& params, const std::filesystem::path& dir,
                                 const ScenarioRecordingOptions& options) {
  checkOptions(options, params.imu_rate_hz);
  const OfficeSetup setup = makeOfficeSetup(params);
  // A scenario without samples: meta, anchors and the truth for the ground truth.
  Scenario s;
  s.params = scenarioParamsOf(params);
  s.p_w_anchors = setup.p_w_anchors;
  s.p_b_tag = params.p_b_tag;
  s.truth = setup.walk;
  s.t0_ns = params.t0_ns;
  const std::vector<std::int64_t> truth_t = groundTruthTimes(s.t0_ns, s.params.duration_s, options.truth_rate_hz);
  const bool tdoa = params.tdoa.enabled;
  const bool ultrasonic = params.ultrasonic.enabled;
  const bool twr = !tdoa || params.tdoa.keep_twr;

  OfficeImuStream imu(params, setup.walk);
  // Work units: an IMU sample, a range slot, a TDoA packet, a ping (estimated), a truth pose.
  const double range_estimate = twr ? params.duration_s * params.range_rate_hz : 0.0;
  const double tdoa_estimate =
      tdoa ? params.duration_s * params.tdoa.round_rate_hz * static_cast<double>(setup.p_w_anchors.size()) : 0.0;
  const double ultrasonic_estimate = ultrasonic ? params.duration_s * params.ultrasonic.ping_rate_hz *
                                                      static_cast<double>(setup.p_w_ultrasonic.size())
                                                : 0.0;
  Progress progress(options, static_cast<double>(imu.size()) + range_estimate + tdoa_estimate + ultrasonic_estimate +
                                 static_cast<double>(truth_t.size()));
  RecordingWriter w(dir, writerOptions(options));
  if (!tdoa && !ultrasonic) {
    writeStatic(w, s.params, s.p_w_anchors, s.p_b_tag, options);
  } else {
    RecordingMeta meta = scenarioMeta(s.params, s.p_b_tag, options);
    std::vector<Anchor> anchors = scenarioAnchors(s.p_w_anchors);
    if (tdoa) meta.ranging = RangingKind::kTdoa;
    if (ultrasonic) {
      meta.ultrasonic_lever_arm_m = params.ultrasonic.p_b_receiver;
      for (std::size_t j = 0; j < setup.p_w_ultrasonic.size(); ++j) {
        Anchor a;
        a.id = ultrasonicAnchorId(setup.p_w_anchors.size(), j);
        a.p_w_anchor = setup.p_w_ultrasonic[j];
        a.kind = AnchorKind::kUltrasonic;
        anchors.push_back(a);
      }
    }
    w.writeMeta(meta);
    w.writeAnchors(anchors);
    w.writeTags({Tag{0, s.p_b_tag}});
  }
  ImuSample m;
  Eigen::Matrix<double, 6, 1> bias;
  while (imu.next(m, bias)) {
    w.write(m);
    progress(static_cast<double>(imu.produced()));
  }
  double done = static_cast<double>(imu.size());
  OfficeStats stats;
  if (twr) {
    OfficeRangeStream ranging(params, setup);
    RangeSample r;
    RangeTruth rt;
    while (ranging.next(r, rt)) {
      w.write(r);
      progress(done + ranging.progress() * range_estimate);
    }
    stats = ranging.stats();
    done += range_estimate;
  } else {
    stats.ranges_per_anchor.assign(setup.p_w_anchors.size(), 0);
  }
  if (tdoa) {
    OfficeTdoaStream stream(params, setup);
    TdoaSample sample;
    TdoaTruth truth;
    while (stream.next(sample, truth)) {
      w.write(sample);
      progress(done + stream.progress() * tdoa_estimate);
    }
    stats.tdoa = stream.stats();
    done += tdoa_estimate;
  }
  if (ultrasonic) {
    OfficeUltrasonicStream stream(params, setup);
    UltrasonicSample sample;
    UltrasonicTruth truth;
    while (stream.next(sample, truth)) {
      w.write(sample);
      progress(done + stream.progress() * ultrasonic_estimate);
    }
    stats.ultrasonic = stream.stats();
    done += ultrasonic_estimate;
  }
  for (std::int64_t t : truth_t) {
    w.write(groundTruthAt(s, t));
    progress(++done);
  }
  w.close();
  progress(done);
  stats.duration_s = params.duration_s;
  stats.imu_samples = imu.size();
  return stats;
}

}  // namespace rilo::sim
