// The configuration schema: one reader per section, each opening its mapping
// with the complete list of accepted keys (config_reader.h). Keys mirror the
// struct fields, with the unit in the name where the struct uses another unit
// (seconds in YAML, nanoseconds in the struct). config/README.md documents
// every key; keep the three in step.
#include "rilod/config.h"

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>

#include "estimation/noise/noise_model_factory.h"
#include "estimation/smoother/smoother_method_names.h"
#include "hal/recording/recording_reader.h"
#include "rilod/config_hardware.h"
#include "rilod/config_reader.h"
#include "rilod/notify.h"

namespace rilo {

using config_detail::ConfigField;
using config_detail::ConfigMap;
using config_detail::ReadContext;

namespace {

constexpr double kHuge = std::numeric_limits<double>::max();

// --- sources -----------------------------------------------------------------

FaultSpec readFault(const ConfigField& field) {
  const ConfigMap m = field.map({"kind", "at_s", "duration_s", "count", "stream"});
  FaultSpec f;
  f.kind = m.require("kind").choice<FaultKind>({{"range_blackout", FaultKind::kRangeBlackout},
                                                {"imu_gap", FaultKind::kImuGap},
                                                {"duplicate", FaultKind::kDuplicate},
                                                {"out_of_order", FaultKind::kOutOfOrder},
                                                {"non_finite", FaultKind::kNonFinite},
                                                {"impossible", FaultKind::kImpossible},
                                                {"far_future", FaultKind::kFarFuture}});
  f.at_s = m.require("at_s").number(0.0, 1e7);
  const std::string kind(toString(f.kind));
  if (f.isWindow()) {
    f.duration_s = m.require("duration_s").positive(1e7);
    if (auto c = m.get("count")) c->fail("count does not apply to " + kind + " (it drops a window: duration_s)");
    if (auto st = m.get("stream")) st->fail("stream does not apply to " + kind);
  } else {
    f.count = m.require("count").integerAs<std::uint32_t>(1, 100'000'000);
    if (auto d = m.get("duration_s")) d->fail("duration_s does not apply to " + kind + " (it counts samples: count)");
    m.read("stream", f.stream, [](const ConfigField& s) {
      return s.choice<FaultStream>({{"all", FaultStream::kAll}, {"imu", FaultStream::kImu}, {"ranging", FaultStream::kRanging}});
    });
  }
  return f;
}

ReplaySourceConfig readReplay(const ConfigField& field) {
  const ConfigMap m = field.map({"path", "pace", "speed", "loop", "shift_to_now", "faults"});
  ReplaySourceConfig c;
  c.path = m.require("path").path();
  m.read("pace", c.pace, [](const ConfigField& f) {
    return f.choice<ReplayPace>({{"real_time", ReplayPace::kRealTime},
                                 {"as_fast_as_possible", ReplayPace::kAsFastAsPossible}});
  });
  m.read("speed", c.speed, [](const ConfigField& f) { return f.positive(1000.0); });
  m.read("loop", c.loop, [](const ConfigField& f) { return f.boolean(); });
  m.read("shift_to_now", c.shift_to_now, [](const ConfigField& f) { return f.boolean(); });
  if (auto f = m.get("faults")) {
    for (const ConfigField& item : f->sequence()) c.faults.push_back(readFault(item));
  }
  if (c.pace == ReplayPace::kAsFastAsPossible && m.has("speed") && c.speed != 1.0) {
    m.require("speed").fail("speed applies to pace real_time only (pace is as_fast_as_possible)");
  }
  return c;
}

SourcesConfig readSources(const ConfigField& field, const std::vector<Anchor>& anchors) {
  const ConfigMap m = field.map({"mode", "replay", "hardware"});
  SourcesConfig c;
  c.mode = m.require("mode").choice<SourceMode>({{"replay", SourceMode::kReplay}, {"hardware", SourceMode::kHardware}});
  // A section of the other mode is still checked (a file that loads is valid
  // as a whole), except that its responders need not be surveyed anchors.
  if (auto f = m.get("replay")) c.replay = readReplay(*f);
  if (auto f = m.get("hardware")) {
    c.hardware = config_detail::readHardware(*f, c.mode == SourceMode::kHardware ? &anchors : nullptr);
  }
  if (c.mode == SourceMode::kReplay && !m.has("replay")) {
    m.require("replay");  // throws: mode replay needs its section
  }
  if (c.mode == SourceMode::kHardware && !m.has("hardware")) m.require("hardware");
  return c;
}

// --- anchors -----------------------------------------------------------------

Anchor readAnchor(const ConfigField& field) {
  const ConfigMap m = field.map({"id", "x", "y", "z", "kind", "sigma"});
  Anchor a;
  a.id = m.require("id").integerAs<std::uint32_t>();
  a.p_w_anchor.x() = m.require("x").number(-1e6, 1e6);
  a.p_w_anchor.y() = m.require("y").number(-1e6, 1e6);
  a.p_w_anchor.z() = m.require("z").number(-1e6, 1e6);
  m.read("kind", a.kind, [](const ConfigField& f) {
    return f.choice<AnchorKind>({{"uwb", AnchorKind::kUwb}, {"ultrasonic", AnchorKind::kUltrasonic}});
  });
  if (auto f = m.get("sigma")) a.sigma_m = f->number(0.0, 100.0);
  return a;
}

std::string readWholeFile(const std::filesystem::path& path, const ConfigField& where) {
  std::ifstream in(path, std::ios::binary);
  if (!in) where.fail("cannot open anchors file '" + path.string() + "': " + std::strerror(errno));
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) where.fail("cannot read anchors file '" + path.string() + "'");
  return text.str();
}

void readAnchors(const ConfigField& field, ServiceConfig& config) {
  if (field.node().IsSequence()) {
    for (const ConfigField& item : field.sequence()) config.anchors.push_back(readAnchor(item));
    // Repeated ids: point at the second one.
    const auto items = field.sequence();
    for (std::size_t i = 0; i < config.anchors.size(); ++i) {
      for (std::size_t j = 0; j < i; ++j) {
        if (config.anchors[i].id == config.anchors[j].id) {
          items[i].fail("anchor id " + std::to_string(config.anchors[i].id) + " repeats " + items[j].keyPath());
        }
      }
    }
  } else if (field.node().IsMap()) {
    const ConfigMap m = field.map({"file"});
    const ConfigField file = m.require("file");
    config.anchors_file = file.path();
    const std::string text = readWholeFile(config.anchors_file, file);
    ReadReport report;
    try {
      config.anchors = recording::parseAnchors(text, config.anchors_file.string(), report);
    } catch (const RecordingError& e) {
      file.fail(std::string("bad anchors file: ") + e.what());
    }
  } else {
    field.fail("expected a list of anchors ({id, x, y, z} items) or a mapping {file: anchors.csv}, got " +
               field.describe());
  }
  const auto uwb = std::count_if(config.anchors.begin(), config.anchors.end(),
                                 [](const Anchor& a) { return a.kind == AnchorKind::kUwb; });
  if (uwb < 3) {
    field.fail("at least 3 UWB anchors are needed (4 not all in one plane for an unambiguous 3D fix), got " +
               std::to_string(uwb));
  }
}

// --- imu ---------------------------------------------------------------------

ImuParams readImu(const ConfigField& field) {
  const ConfigMap m = field.map({"gyro_noise_density", "accel_noise_density", "gyro_bias_random_walk",
                                 "accel_bias_random_walk", "gyro_bias_tau_s", "accel_bias_tau_s",
                                 "integration_noise_density", "gravity_m_s2"});
  ImuParams p;
  auto density = [](const ConfigField& f) { return f.positive(1.0); };
  m.read("gyro_noise_density", p.gyro_noise_density, density);
  m.read("accel_noise_density", p.accel_noise_density, density);
  m.read("gyro_bias_random_walk", p.gyro_bias_random_walk, density);
  m.read("accel_bias_random_walk", p.accel_bias_random_walk, density);
  auto tau = [](const ConfigField& f) {
    const double t = f.number(0.0, kHuge, /*allow_inf=*/true);
    if (!(t > 0.0)) f.fail("expected a correlation time > 0 s (.inf for a random walk), got " + f.node().Scalar());
    return t;
  };
  m.read("gyro_bias_tau_s", p.gyro_bias_tau_s, tau);
  m.read("accel_bias_tau_s", p.accel_bias_tau_s, tau);
  m.read("integration_noise_density", p.integration_noise_density, density);
  m.read("gravity_m_s2", p.gravity_m_s2, [](const ConfigField& f) { return f.number(9.7, 9.9); });
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    field.fail(e.what());
  }
  return p;
}

// --- estimator ---------------------------------------------------------------

void readRelinearization(const ConfigField& field, SmootherParams& s) {
  const ConfigMap m = field.map({"skip", "interval_s", "rotation_rad", "position_m", "velocity_m_s", "anchor_m",
                                 "accel_bias_m_s2", "gyro_bias_rad_s", "together", "max_variables",
                                 "recent_updates", "wildfire_threshold", "after_rejection_s"});
  auto threshold = [](const ConfigField& f) { return f.number(0.0, 1e3); };
  m.read("skip", s.relinearize_skip, [](const ConfigField& f) { return f.integerAs<int>(1, 1000); });
  m.read("interval_s", s.relinearize_interval_s, [](const ConfigField& f) { return f.number(0.0, 3600.0); });
  if (auto f = m.get("rotation_rad")) s.default_pose_threshold.head<3>().setConstant(threshold(*f));
  if (auto f = m.get("position_m")) s.default_pose_threshold.tail<3>().setConstant(threshold(*f));
  if (auto f = m.get("velocity_m_s")) s.default_vec3_threshold.setConstant(threshold(*f));
  if (auto f = m.get("anchor_m")) s.relinearize_thresholds3['l'] = Vec3::Constant(threshold(*f));
  if (auto f = m.get("accel_bias_m_s2")) s.default_bias_threshold.head<3>().setConstant(threshold(*f));
  if (auto f = m.get("gyro_bias_rad_s")) s.default_bias_threshold.tail<3>().setConstant(threshold(*f));
  m.read("together", s.relinearize_together, [](const ConfigField& f) { return f.boolean(); });
  m.read("max_variables", s.max_relinearized_variables,
         [](const ConfigField& f) { return f.integerAs<int>(0, 1'000'000); });
  m.read("recent_updates", s.always_relinearize_recent_updates,
         [](const ConfigField& f) { return f.integerAs<int>(0, 1000); });
  if (s.dampedWithStalePreviousState()) m.require("recent_updates").fail(SmootherParams::kDampedNeedsRecentRelinearization);
  m.read("wildfire_threshold", s.wildfire_threshold, threshold);
  m.read("after_rejection_s", s.after_rejection_max_age_s, [](const ConfigField& f) { return f.number(0.0, 3600.0); });
}

void readDamping(const ConfigField& field, SmootherParams& s) {
  const ConfigMap m = field.map({"lambda_initial", "lambda_min", "lambda_max", "lambda_increase",
                                 "lambda_decrease", "widen", "acceptance", "tie_tolerance"});
  auto lambda = [](const ConfigField& f) { return f.positive(1e20); };
  m.read("lambda_initial", s.d_isam2.lambda_initial, lambda);
  m.read("lambda_min", s.d_isam2.lambda_min, lambda);
  m.read("lambda_max", s.d_isam2.lambda_max, lambda);
  m.read("lambda_increase", s.d_isam2.lambda_increase, [](const ConfigField& f) { return f.number(1.0, 1e6); });
  m.read("lambda_decrease", s.d_isam2.lambda_decrease, [](const ConfigField& f) { return f.number(0.0, 1.0); });
  m.read("widen", s.d_isam2.widen_damping, [](const ConfigField& f) { return f.boolean(); });
  m.read("tie_tolerance", s.d_isam2.tie_tolerance, [](const ConfigField& f) { return f.number(0.0, 1e3); });
  m.read("acceptance", s.d_isam2.acceptance, [](const ConfigField& f) {
    return f.choice<DIsam2Params::Acceptance>({{"damped_factors", DIsam2Params::Acceptance::kDampedFactors},
                                               {"global", DIsam2Params::Acceptance::kGlobal}});
  });
}

void readTrustRegion(const ConfigField& field, SmootherParams& s) {
  const ConfigMap m = field.map({"initial", "min"});
  m.read("initial", s.dogleg.trust_radius_initial, [](const ConfigField& f) { return f.positive(1e6); });
  m.read("min", s.dogleg.trust_radius_min, [](const ConfigField& f) { return f.positive(1e6); });
}

void readRange(const ConfigField& field, EstimatorConfig& e) {
  const ConfigMap m = field.map({"noise_model", "sigma_m", "huber_k", "cauchy_c", "nlos_scale_m", "nlos_weight",
                                 "nlos_power_gap_db", "flagged_nlos_weight", "flagged_nlos_scale_m", "flagged_nlos_component",
                                 "flagged_scale_reference_hz", "flagged_excess_quantile", "los_gap_calibration", "rx_level_indicator",
                                 "nlos_memory_s",
                                 "lever_arm_m", "same_state_window_s", "max_state_interval_s", "max_wait_s"});
  RangeImuGraphParams& g = e.graph;
  if (auto f = m.get("noise_model")) {
    const std::string name = f->string();
    const auto& names = rangeLossNames();
    if (std::find(names.begin(), names.end(), name) == names.end()) {
      std::string list;
      for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
      f->fail("expected one of " + list + ", got '" + name + "'");
    }
    g.range_loss = name;
  }
  m.read("sigma_m", g.range_noise.sigma_m, [](const ConfigField& f) { return f.positive(100.0); });
  m.read("huber_k", g.range_noise.huber_k, [](const ConfigField& f) { return f.positive(100.0); });
  m.read("cauchy_c", g.range_noise.cauchy_c, [](const ConfigField& f) { return f.positive(100.0); });
  if (auto f = m.get("nlos_scale_m")) g.range_noise.nlos_scale_m = f->positive(100.0);
  m.read("nlos_weight", g.range_noise.nlos_weight, [](const ConfigField& f) { return f.number(0.0, 0.5); });
  m.read("nlos_power_gap_db", g.range_noise.nlos_power_gap_db,
         [](const ConfigField& f) { return f.number(0.0, std::numeric_limits<double>::infinity(), true); });
  m.read("flagged_nlos_weight", g.range_noise.flagged_nlos_weight, [](const ConfigField& f) { return f.number(0.0, 0.5); });
  if (auto f = m.get("flagged_nlos_scale_m")) g.range_noise.flagged_nlos_scale_m = f->positive(100.0);
  if (auto f = m.get("flagged_nlos_component")) g.range_noise.flagged_nlos_component = f->boolean();
  m.read("flagged_scale_reference_hz", g.range_noise.flagged_scale_reference_hz,
         [](const ConfigField& f) { return f.number(0.0, 1e4); });
  m.read("flagged_excess_quantile", e.flagged_excess_quantile, [](const ConfigField& f) { return f.number(0.0, 1.0); });
  if (auto f = m.get("los_gap_calibration")) e.los_gap_calibration = f->boolean();
  if (auto f = m.get("rx_level_indicator")) e.rx_level_indicator = f->boolean();
  m.read("nlos_memory_s", e.nlos_memory_s, [](const ConfigField& f) { return f.number(0.0, 60.0); });
  m.read("lever_arm_m", g.p_b_tag, [](const ConfigField& f) {
    const Vec3 v = f.vec3();
    if (v.norm() > 5.0) f.fail("expected a lever arm of at most 5 m, got " + std::to_string(v.norm()) + " m");
    return v;
  });
  m.read("same_state_window_s", g.same_state_window_ns, [](const ConfigField& f) { return f.secondsAsNs(0.0, 1.0); });
  m.read("max_state_interval_s", g.max_state_interval_ns,
         [](const ConfigField& f) { return f.secondsAsNs(1e-3, 60.0); });
  m.read("max_wait_s", e.stream.max_range_wait_ns, [](const ConfigField& f) { return f.secondsAsNs(1e-3, 600.0); });
  if (e.stream.max_range_wait_ns < g.max_state_interval_ns) {
    (m.has("max_wait_s") ? m.require("max_wait_s") : field)
        .fail("max_wait_s must be >= max_state_interval_s (" + std::to_string(g.max_state_interval_ns * 1e-9) + " s)");
  }
  try {
    (void)makeRangeLoss(g.range_loss, g.range_noise);
  } catch (const std::invalid_argument& e2) {
    field.fail(e2.what());
  }
}

EstimatorConfig readEstimator(const ConfigField& field, EstimatorConfig e) {
  const ConfigMap m = field.map({"smoother", "lag_s", "relinearization", "damping", "trust_region", "range",
                                 "anchors_as_variables", "anchor_sigma_m", "init", "height_band",
                                 "vertical_speed_sigma_m_s", "vertical_speed_correlation_s", "zero_velocity_sigma_m_s",
                                 "max_outside_anchors_m",
                                 "tdoa", "input_screen"});
  m.read("smoother", e.smoother.method, [](const ConfigField& f) {
    return f.choice<SmootherParams::Method>(kSmootherMethodNames);
  });
  m.read("lag_s", e.smoother.lag_s, [](const ConfigField& f) {
    const double lag = f.number(0.0, 3600.0);
    if (!(lag > 0.0)) f.fail("expected a lag > 0 s (the service must bound its memory), got " + f.node().Scalar());
    return lag;
  });
  if (auto f = m.get("relinearization")) readRelinearization(*f, e.smoother);
  if (auto f = m.get("damping")) readDamping(*f, e.smoother);
  if (auto f = m.get("trust_region")) readTrustRegion(*f, e.smoother);
  if (auto f = m.get("range")) readRange(*f, e);
  m.read("anchors_as_variables", e.graph.anchors_as_variables, [](const ConfigField& f) { return f.boolean(); });
  m.read("anchor_sigma_m", e.graph.anchor_sigma_m, [](const ConfigField& f) { return f.positive(100.0); });
  if (auto f = m.get("init")) {
    const ConfigMap init = f->map({"window_s", "max_outside_anchors_m", "heavy_nlos_after_s", "attempt_budget_s"});
    init.read("window_s", e.init_window_s, [](const ConfigField& w) { return w.number(0.5, 600.0); });
    init.read("max_outside_anchors_m", e.init_max_outside_anchors_m, [](const ConfigField& w) {
      return w.number(0.0, std::numeric_limits<double>::infinity(), true);  // >= 0 (m) or .inf
    });
    init.read("heavy_nlos_after_s", e.init_heavy_nlos_after_s, [](const ConfigField& w) {
      return w.number(0.0, std::numeric_limits<double>::infinity(), true);  // >= 0 (s) or .inf
    });
    init.read("attempt_budget_s", e.init_attempt_budget_s, [](const ConfigField& w) {
      return w.number(0.1, std::numeric_limits<double>::infinity(), true);  // >= 0.1 (s) or .inf
    });
  }
  if (auto f = m.get("height_band")) {
    const ConfigMap band = f->map({"enabled", "floor_z_m", "min_height_m", "max_height_m", "sigma_m", "range_lever",
                                   "hold_sigma_m", "learn_carry_height", "carry_memory_s"});
    band.read("enabled", e.height_band.enabled, [](const ConfigField& b) { return b.boolean(); });
    band.read("floor_z_m", e.height_band.floor_z_m, [](const ConfigField& b) { return b.number(-1e4, 1e4); });
    band.read("min_height_m", e.height_band.min_height_m, [](const ConfigField& b) { return b.number(-100.0, 100.0); });
    band.read("max_height_m", e.height_band.max_height_m, [](const ConfigField& b) { return b.number(-100.0, 100.0); });
    band.read("sigma_m", e.height_band.sigma_m, [](const ConfigField& b) { return b.positive(100.0); });
    band.read("range_lever", e.height_band.range_lever, [](const ConfigField& b) { return b.boolean(); });
    band.read("hold_sigma_m", e.height_band.hold_sigma_m, [](const ConfigField& b) { return b.number(0.0, 100.0); });
    band.read("learn_carry_height", e.height_band.learn_carry_height, [](const ConfigField& b) { return b.boolean(); });
    band.read("carry_memory_s", e.height_band.carry_memory_s, [](const ConfigField& b) { return b.positive(1e6); });
    try {
      e.height_band.validate("height_band");
    } catch (const std::invalid_argument& ex) {
      f->fail(ex.what());
    }
  }
  if (auto f = m.get("tdoa")) {
    const ConfigMap t =
        f->map({"state_window_s", "dynamic_covariance", "nlos_indicator", "max_power_gap_db", "gap_excess"});
    t.read("state_window_s", e.with_tdoa.state_window_ns, [](const ConfigField& w) { return w.secondsAsNs(0.0, 1.0); });
    t.read("dynamic_covariance", e.with_tdoa.dynamic_covariance, [](const ConfigField& d) { return d.boolean(); });
    t.read("nlos_indicator", e.graph.tdoa_nlos_indicator, [](const ConfigField& d) { return d.boolean(); });
    t.read("max_power_gap_db", e.graph.tdoa_max_power_gap_db, [](const ConfigField& d) {
      return d.number(0.0, std::numeric_limits<double>::infinity(), true);  // dB, or .inf: none gated
    });
    t.read("gap_excess", e.graph.tdoa_gap_excess.enabled, [](const ConfigField& d) { return d.boolean(); });
    if (e.with_tdoa.state_window_ns >= e.graph.max_state_interval_ns) {
      (t.has("state_window_s") ? t.require("state_window_s") : *f)
          .fail("state_window_s must be below range.max_state_interval_s (" +
                std::to_string(static_cast<double>(e.graph.max_state_interval_ns) * 1e-9) + " s)");
    }
  } else if (e.with_tdoa.state_window_ns >= e.graph.max_state_interval_ns) {
    (m.has("range") ? m.require("range") : field)
        .fail("max_state_interval_s must exceed tdoa.state_window_s (" +
              std::to_string(static_cast<double>(e.with_tdoa.state_window_ns) * 1e-9) + " s; set it in a tdoa section)");
  }
  if (auto f = m.get("input_screen")) {
    const ConfigMap s = f->map(
        {"max_range_m", "max_accel_m_s2", "max_gyro_rad_s", "max_time_jump_s", "max_imu_jump_s", "jump_confirmations"});
    s.read("max_range_m", e.input_screen.max_range_m, [](const ConfigField& v) { return v.positive(1e5); });
    s.read("max_accel_m_s2", e.input_screen.max_accel_m_s2, [](const ConfigField& v) { return v.positive(1e5); });
    s.read("max_gyro_rad_s", e.input_screen.max_gyro_rad_s, [](const ConfigField& v) { return v.positive(1e4); });
    s.read("max_time_jump_s", e.input_screen.max_time_jump_s, [](const ConfigField& v) { return v.number(0.01, 3600.0); });
    s.read("max_imu_jump_s", e.input_screen.max_imu_jump_s, [](const ConfigField& v) { return v.number(0.01, 3600.0); });
    s.read("jump_confirmations", e.input_screen.jump_confirmations, [](const ConfigField& v) {
      return static_cast<int>(v.integer(1, 1000));
    });
    e.input_screen_imu_bounds_given = s.has("max_accel_m_s2") || s.has("max_gyro_rad_s");
  }
  m.read("max_outside_anchors_m", e.max_outside_anchors_m, [](const ConfigField& f) {
    const double v = f.number(0.0, std::numeric_limits<double>::infinity(), true);  // as positive(), with .inf
    if (!(v > 0.0)) f.fail("expected a number > 0 (m) or .inf, got " + f.node().Scalar());
    return v;
  });
  m.read("vertical_speed_sigma_m_s", e.vertical_speed_sigma_m_s, [](const ConfigField& f) -> std::optional<double> {
    if (f.node().IsScalar() && f.node().Scalar() == "auto") return std::nullopt;
    char* end = nullptr;
    const std::string text = f.node().IsScalar() ? f.node().Scalar() : std::string();
    if (f.node().IsScalar() && (std::strtod(text.c_str(), &end), end == text.c_str())) {
      f.fail("expected a number (m/s) or auto, got '" + text + "'");
    }
    return f.number(0.0, 100.0);
  });
  m.read("vertical_speed_correlation_s", e.graph.vertical_speed_correlation_s,
         [](const ConfigField& f) { return f.positive(10.0); });
  m.read("zero_velocity_sigma_m_s", e.zero_velocity_sigma_m_s, [](const ConfigField& f) { return f.number(0.0, 100.0); });
  try {
    e.smoother.validate();
  } catch (const std::invalid_argument& ex) {
    // "SmootherParams.lambda_max must be >= lambda_min": point at the damping
    // or trust_region section when the field belongs there.
    const std::string what = ex.what();
    const bool damping = what.find("lambda") != std::string::npos;
    const bool trust = what.find("trust_radius") != std::string::npos;
    if (damping && m.has("damping")) m.require("damping").fail(what);
    if (trust && m.has("trust_region")) m.require("trust_region").fail(what);
    field.fail(what);
  }
  return e;
}

// --- dds ---------------------------------------------------------------------

std::string readTopicName(const ConfigField& f) {
  const std::string name = f.string();
  const bool chars_ok = std::all_of(name.begin(), name.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' || c == '/';
  });
  if (!chars_ok || name.front() == '/' || name.back() == '/' || name.find("//") != std::string::npos) {
    f.fail("expected a DDS topic name of letters, digits, '_' and inner '/' (ROS 2: \"rt/<ros name>\"), got '" +
           name + "'");
  }
  return name;
}

/// A topic name, or "" for a topic not published (TF).
std::string readOptionalTopicName(const ConfigField& f) {
  return f.string(/*allow_empty=*/true).empty() ? std::string() : readTopicName(f);
}

std::string readFrameId(const ConfigField& f) {
  const std::string id = f.string();
  if (std::any_of(id.begin(), id.end(), [](char c) { return c == ' ' || c == '\t' || c == '\n'; })) {
    f.fail("expected a frame id without whitespace, got '" + id + "'");
  }
  return id;
}

DdsConfig readDds(const ConfigField& field) {
  const ConfigMap m = field.map({"domain", "loopback_only", "cyclone_config_file", "stamp_clock", "topics", "frames"});
  DdsConfig c;
  m.read("stamp_clock", c.stamp_clock, [](const ConfigField& f) {
    return f.choice<dds::StampClock>({{"system", dds::StampClock::kSystem}, {"monotonic", dds::StampClock::kMonotonic}});
  });
  m.read("domain", c.domain_id, [](const ConfigField& f) { return f.integerAs<std::uint32_t>(0, 232); });
  m.read("loopback_only", c.loopback_only, [](const ConfigField& f) { return f.boolean(); });
  if (auto f = m.get("cyclone_config_file")) {
    c.cyclone_config_file = f->path();
    if (c.loopback_only) f->fail("give either loopback_only: true or cyclone_config_file, not both");
  }
  if (auto f = m.get("topics")) {
    const ConfigMap t = f->map({"odometry", "pose", "status", "tf", "ranges"});
    t.read("odometry", c.topics.odometry, readTopicName);
    t.read("pose", c.topics.pose, readTopicName);
    t.read("status", c.topics.status, readTopicName);
    t.read("tf", c.topics.tf, readOptionalTopicName);
    t.read("ranges", c.topics.ranges, readOptionalTopicName);
    // Pairwise (tf and ranges may be empty: not published).
    const std::string* names[] = {&c.topics.odometry, &c.topics.pose, &c.topics.status, &c.topics.tf,
                                  &c.topics.ranges};
    for (std::size_t i = 0; i < std::size(names); ++i) {
      for (std::size_t j = i + 1; j < std::size(names); ++j) {
        if (!names[i]->empty() && *names[i] == *names[j]) {
          f->fail("the odometry, pose, status, tf and ranges topics must have different names");
        }
      }
    }
  }
  if (auto f = m.get("frames")) {
    const ConfigMap fr = f->map({"world", "body"});
    fr.read("world", c.frames.world, readFrameId);
    fr.read("body", c.frames.body, readFrameId);
    if (c.frames.world == c.frames.body) f->fail("world and body frame ids must differ");
  }
  return c;
}

// --- recording, realtime, status, watchdog -------------------------------------

RecordingConfig readRecording(const ConfigField& field) {
  const ConfigMap m = field.map({"enabled", "directory", "flush_interval_s", "sync"});
  RecordingConfig c;
  m.read("enabled", c.enabled, [](const ConfigField& f) { return f.boolean(); });
  m.read("directory", c.directory, [](const ConfigField& f) { return f.path(); });
  m.read("flush_interval_s", c.flush_interval_ns, [](const ConfigField& f) { return f.secondsAsNs(0.001, 60.0); });
  m.read("sync", c.sync, [](const ConfigField& f) { return f.boolean(); });
  return c;
}

void readThread(const ConfigField& field, ThreadRealtimeSettings& t) {
  const ConfigMap m = field.map({"name", "priority", "cpus"});
  if (auto f = m.get("name")) {
    t.name = f->string();
    if (t.name.size() > 15) f->fail("expected a thread name of at most 15 characters (Linux), got '" + t.name + "'");
  }
  m.read("priority", t.fifo_priority, [](const ConfigField& f) { return f.integerAs<int>(0, 99); });
  if (auto f = m.get("cpus")) {
    t.cpus.clear();
    for (const ConfigField& cpu : f->sequence()) {
      const int index = cpu.integerAs<int>(0, 1023);
      if (std::find(t.cpus.begin(), t.cpus.end(), index) != t.cpus.end()) {
        cpu.fail("CPU " + std::to_string(index) + " is listed twice");
      }
      t.cpus.push_back(index);
    }
  }
}

RealtimeConfig readRealtime(const ConfigField& field) {
  const ConfigMap m = field.map({"lock_memory", "heap_reserve_mb", "stack_prefault_kb", "queue_capacity", "threads"});
  RealtimeConfig c;
  m.read("lock_memory", c.process.lock_memory, [](const ConfigField& f) { return f.boolean(); });
  m.read("heap_reserve_mb", c.process.heap_reserve_bytes,
         [](const ConfigField& f) { return f.integerAs<std::size_t>(0, 4096) << 20; });
  m.read("stack_prefault_kb", c.process.stack_prefault_bytes,
         [](const ConfigField& f) { return f.integerAs<std::size_t>(0, 7 * 1024) << 10; });
  m.read("queue_capacity", c.queue_capacity, [](const ConfigField& f) { return f.integerAs<std::size_t>(16, 1u << 22); });
  if (auto f = m.get("threads")) {
    const ConfigMap t = f->map({"imu_source", "uwb_source", "replay_source", "publisher", "estimator", "recorder"});
    if (auto g = t.get("imu_source")) readThread(*g, c.imu_source);
    if (auto g = t.get("uwb_source")) readThread(*g, c.uwb_source);
    if (auto g = t.get("replay_source")) readThread(*g, c.replay_source);
    if (auto g = t.get("publisher")) readThread(*g, c.publisher);
    if (auto g = t.get("estimator")) readThread(*g, c.estimator);
    if (auto g = t.get("recorder")) readThread(*g, c.recorder);
  }
  return c;
}

StatusConfig readStatus(const ConfigField& field) {
  const ConfigMap m = field.map({"period_s", "imu_timeout_s", "range_timeout_s"});
  StatusConfig c;
  m.read("period_s", c.period_ns, [](const ConfigField& f) { return f.secondsAsNs(0.01, 3600.0); });
  m.read("imu_timeout_s", c.imu_timeout_ns, [](const ConfigField& f) { return f.secondsAsNs(0.001, 60.0); });
  m.read("range_timeout_s", c.range_timeout_ns, [](const ConfigField& f) { return f.secondsAsNs(0.01, 600.0); });
  return c;
}

WatchdogConfig readWatchdog(const ConfigField& field) {
  const ConfigMap m = field.map({"enabled", "heartbeat_timeout_s", "startup_grace_s"});
  WatchdogConfig c;
  m.read("enabled", c.enabled, [](const ConfigField& f) { return f.boolean(); });
  m.read("heartbeat_timeout_s", c.heartbeat_timeout_ns,
         [](const ConfigField& f) { return f.secondsAsNs(0.01, 600.0); });
  m.read("startup_grace_s", c.startup_grace_ns, [](const ConfigField& f) { return f.secondsAsNs(0.0, 3600.0); });
  // Under a systemd watchdog (WATCHDOG_USEC for this process) the timeout
  // must fit in the unit's period (issue 37: 100 s was taken under WatchdogSec=5).
  if (const auto interval = notify::watchdogInterval(); interval && c.enabled) {
    const std::string problem = notify::heartbeatTimeoutProblem(c.heartbeat_timeout_ns, *interval);
    if (!problem.empty()) (m.has("heartbeat_timeout_s") ? m.require("heartbeat_timeout_s") : field).fail(problem);
  }
  return c;
}

ServiceConfig readRoot(const ConfigField& root_field, const std::filesystem::path& file) {
  if (root_field.isNull()) root_field.fail("the configuration is empty (expected a mapping with sources and anchors)");
  const ConfigMap root = root_field.map(
      {"sources", "anchors", "imu", "estimator", "dds", "recording", "realtime", "status", "watchdog"});
  ServiceConfig c;
  c.file = file;
  // Anchors first: the hardware section refers to them.
  const ConfigField sources = root.require("sources");
  readAnchors(root.require("anchors"), c);
  c.sources = readSources(sources, c.anchors);
  if (auto f = root.get("imu")) c.estimator.graph.imu = readImu(*f);
  if (auto f = root.get("estimator")) c.estimator = readEstimator(*f, c.estimator);
  if (auto f = root.get("dds")) c.dds = readDds(*f);
  if (auto f = root.get("recording")) c.recording = readRecording(*f);
  if (auto f = root.get("realtime")) c.realtime = readRealtime(*f);
  if (auto f = root.get("status")) c.status = readStatus(*f);
  if (auto f = root.get("watchdog")) c.watchdog = readWatchdog(*f);
  return c;
}

EstimatorConfig readEstimatorOnly(const ConfigField& root_field) {
  if (root_field.isNull()) root_field.fail("the configuration is empty (expected a mapping with an estimator section)");
  const ConfigMap root = root_field.map(
      {"sources", "anchors", "imu", "estimator", "dds", "recording", "realtime", "status", "watchdog"});
  EstimatorConfig e;
  if (auto f = root.get("imu")) e.graph.imu = readImu(*f);
  if (auto f = root.get("estimator")) e = readEstimator(*f, e);
  return e;
}

/// Parses `yaml` and hands its root to `read` (a ConfigError names `file`).
template <typename Read>
auto parseDocument(std::string_view yaml, const std::filesystem::path& file, Read read) {
  const std::filesystem::path absolute = std::filesystem::absolute(file).lexically_normal();
  const ReadContext context{file.string(), absolute.parent_path()};
  YAML::Node doc;
  try {
    doc = YAML::Load(std::string(yaml));
  } catch (const YAML::Exception& e) {
    config_detail::failAt(context, "", e.mark, "not valid YAML: " + e.msg);
  }
  return read(ConfigField(doc, "", &context), absolute);
}

}  // namespace

ServiceConfig parseServiceConfig(std::string_view yaml, const std::filesystem::path& file) {
  return parseDocument(yaml, file, [](const ConfigField& root, const std::filesystem::path& absolute) {
    return readRoot(root, absolute);
  });
}

EstimatorConfig parseEstimatorConfig(std::string_view yaml, const std::filesystem::path& file) {
  return parseDocument(yaml, file,
                       [](const ConfigField& root, const std::filesystem::path&) { return readEstimatorOnly(root); });
}

ServiceConfig loadServiceConfig(const std::filesystem::path& file) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) {
    throw ConfigError(file.string(), "", 0, 0, "is a directory, expected a YAML configuration file");
  }
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw ConfigError(file.string(), "", 0, 0, std::string("cannot open the configuration file: ") + std::strerror(errno));
  }
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ConfigError(file.string(), "", 0, 0, "cannot read the configuration file");
  return parseServiceConfig(text.str(), file);
}

std::string_view toString(SourceMode mode) { return mode == SourceMode::kReplay ? "replay" : "hardware"; }
std::string_view toString(ReplayPace pace) {
  return pace == ReplayPace::kRealTime ? "real_time" : "as_fast_as_possible";
}
}  // namespace rilo
