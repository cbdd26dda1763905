#include "replay_command.h"
#include "shipped_config.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

#include "evaluation/replay_run.h"
#include "evaluation/tum.h"
#include "hal/recording/recording_reader.h"
#include "rilod/config.h"
#include "rilod/service_setup.h"
#include "replay_view.h"
#include "unsigned_option.h"

namespace rilo::tool {

namespace {

using Json = nlohmann::ordered_json;

Json statsJson(const PositionErrorStats& s) {
  // No poses, no error: nulls, never zeros a script would read as perfect (issue 37).
  const bool any = s.ape_3d.count > 0;
  const auto fig = [&](double v) { return any ? Json(v) : Json(nullptr); };
  return Json{{"poses", s.ape_3d.count},
              {"mean_m", fig(s.ape_3d.mean)},
              {"median_m", fig(s.ape_3d.median)},
              {"rmse_m", fig(s.ape_3d.rmse)},
              {"max_m", fig(s.ape_3d.max)},
              {"horizontal_mean_m", fig(s.ape_horizontal.mean)},
              {"vertical_mean_m", fig(s.ape_vertical.mean)},
              {"vertical_bias_m", fig(s.vertical_bias_m)}};
}

/// A figure, or null when there is none (nlohmann writes NaN and inf as null too).
Json optionalJson(const std::optional<double>& v) { return v ? Json(*v) : Json(nullptr); }

/// {"not_finite": n, ..., "time_jumps": n}: the physical screen's counts.
Json inputDroppedJson(const InputDropCounts& d) {
  Json out = Json::object();
  for (int r = 0; r < static_cast<int>(InputDrop::kCount); ++r) {
    out[std::string(inputDropName(static_cast<InputDrop>(r)))] = d.by_reason[r];
  }
  out["time_jumps"] = d.time_jumps;
  return out;
}

/// "far_future 1, out_of_bounds 3" (reasons with a count only).
std::string inputDroppedText(const InputDropCounts& d) {
  std::string out;
  for (int r = 0; r < static_cast<int>(InputDrop::kCount); ++r) {
    if (d.by_reason[r] == 0) continue;
    if (!out.empty()) out += ", ";
    out += std::string(inputDropName(static_cast<InputDrop>(r))) + ' ' + std::to_string(d.by_reason[r]);
  }
  return out;
}

Json consistencyJson(const CovarianceConsistency& c) {
  // No poses: nulls, as statsJson.
  const auto fig = [&](double v) { return c.poses > 0 ? Json(v) : Json(nullptr); };
  return Json{{"poses", c.poses},
              {"not_positive_definite", c.not_positive_definite},
              {"horizontal_in_95", fig(c.horizontal_in_95)},
              {"vertical_in_95", fig(c.vertical_in_95)},
              {"nees_mean", fig(c.nees_mean)},
              {"sigma_horizontal_m", fig(c.sigma_horizontal_m)},
              {"error_horizontal_m", fig(c.error_horizontal_m)},
              {"sigma_vertical_m", fig(c.sigma_vertical_m)},
              {"error_vertical_m", fig(c.error_vertical_m)}};
}

Json countJson(const MeasurementCount& c, bool with_flags = false) {
  Json out{{"recorded", c.recorded}, {"used", c.used}, {"dropped", c.dropped}, {"selected", c.selected}};
  if (with_flags) {
    out["flagged_one"] = c.flagged_one;
    out["flagged_both"] = c.flagged_both;
    out["deep_nlos"] = c.deep_nlos;
  }
  return out;
}

}  // namespace

namespace {

void applyEstimator(const EstimatorConfig& estimator, LocalizerParams params, GivenOptions given,
                    ReplaySettings& settings) {
  settings.service_params = std::move(params);
  if (!given.smoother) settings.smoother = smootherMethodName(estimator.smoother.method);
  if (!given.noise) settings.noise = estimator.graph.range_loss;
  if (!given.lag) settings.lag_s = estimator.smoother.lag_s;
}

}  // namespace

void applyServiceConfig(const std::string& config_file, GivenOptions given, ReplaySettings& settings) {
  const ServiceConfig cfg = loadServiceConfig(config_file);
  applyEstimator(cfg.estimator, localizerParams(cfg), given, settings);
}

void applyShippedConfig(GivenOptions given, ReplaySettings& settings) {
  const EstimatorConfig estimator = parseEstimatorConfig(shippedConfigYaml(), std::string(kShippedConfigName));
  applyEstimator(estimator, localizerParams(estimator), given, settings);
}

int runReplay(const ReplayOptions& o) {
  ReadReport read_report;
  const Recording rec = readRecording(o.recording, &read_report);
  // What the reader accepted with a remark (a duplicate row skipped, an
  // unknown meta.yaml key, a cut-off last line): each once, with its file and line.
  for (const ReadWarning& w : read_report.warnings) spdlog::warn("{}", w.message);
  const ReplayResult run = replayRecording(rec, o.settings);

  const std::filesystem::path dir(o.out);
  std::filesystem::create_directories(dir);
  {
    std::ofstream timing(dir / "timing.csv");
    timing << "t_s,update_ms,cliques_reeliminated,variables_relinearized,tries,accepted,lambda,"
              "cliques_back_substituted,factors_linearized,variables_marginalized,cliques_total\n";
    for (const ReplayUpdate& u : run.updates) {
      timing << static_cast<double>(u.t_ns) * 1e-9 << ',' << u.stats.time_s * 1e3 << ',' << u.stats.cliques_reeliminated
             << ',' << u.stats.variables_relinearized << ',' << u.stats.step_tries << ','
             << (u.stats.step_accepted ? 1 : 0) << ',' << u.stats.lambda << ',' << u.stats.cliques_back_substituted << ','
             << u.stats.factors_linearized << ',' << u.stats.variables_marginalized << ',' << u.stats.cliques_total << '\n';
    }
    if (!timing) throw std::runtime_error("cannot write " + (dir / "timing.csv").string());
  }
  writeTum(dir / "online.tum", run.online);
  if (!run.position_only.empty()) writeTum(dir / "position_only.tum", run.position_only);
  writeTum(dir / "smoothed.tum", run.smoothed);
  {
    // The published positions' covariance (world, m^2), which TUM cannot hold.
    std::ofstream cov(dir / "covariance.csv");
    cov << "t_s,x_m,y_m,z_m,cov_xx,cov_xy,cov_xz,cov_yy,cov_yz,cov_zz,position_only\n";
    for (const TimedPositionCovariance& c : run.published_covariance) {
      const Mat3& P = c.cov_p_w;
      // Times as in the TUM files (ns exact at epoch seconds), the rest to 10 digits.
      char row[320];
      std::snprintf(row, sizeof row, ",%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%.10g,%d\n", c.p_w.x(),
                    c.p_w.y(), c.p_w.z(), P(0, 0), P(0, 1), P(0, 2), P(1, 1), P(1, 2), P(2, 2), c.position_only ? 1 : 0);
      cov << secondsText(c.t_ns) << row;
    }
    if (!cov) throw std::runtime_error("cannot write " + (dir / "covariance.csv").string());
  }
  // The truth beside the estimates, for evo (`evo_ape tum groundtruth.tum online.tum`).
  if (!rec.groundtruth.empty()) {
    TumTrajectory truth;
    truth.reserve(rec.groundtruth.size());
    for (const GroundTruthPose& g : rec.groundtruth) truth.push_back({g.t_ns, g.pose()});
    writeTum(dir / "groundtruth.tum", truth);
  }

  std::vector<double> sorted;
  for (const ReplayUpdate& u : run.updates) sorted.push_back(u.stats.time_s * 1e3);
  std::sort(sorted.begin(), sorted.end());
  double mean_ms = 0.0;
  for (double x : sorted) mean_ms += x / static_cast<double>(sorted.size());
  const double p99_ms = sorted.empty() ? 0.0 : sorted[static_cast<std::size_t>(0.99 * static_cast<double>(sorted.size() - 1))];
  const double max_ms = sorted.empty() ? 0.0 : sorted.back();

  Json j;
  j["recording"] = o.recording;
  // The configuration the replay ran: a file, the built-in one, or none.
  j["config"] = o.library_defaults ? Json(nullptr) : Json(o.config.empty() ? std::string(kShippedConfigName) : o.config);
  j["device_from"] = o.settings.device_from_recording ? "recording" : "config";
  j["smoother"] = o.settings.smoother;
  j["noise"] = o.settings.noise;
  j["lag_s"] = o.settings.lag_s;
  j["range_hz"] = o.settings.range_hz;
  j["thinning"] = rangeThinningName(o.settings.thinning);
  j["ranges_used"] = run.ranges_used;
  j["measurements"] = Json{{"selected", toString(o.settings.measurements)},
                           {"reception", o.settings.reception},
                           {"reception_seed", o.settings.reception_seed},
                           {"range", countJson(run.measurements.range)},
                           {"tdoa", countJson(run.measurements.tdoa, true)},
                           {"ultrasonic", countJson(run.measurements.ultrasonic)}};
  j["dynamic_covariance"] = run.dynamic_covariance;
  j["updates"] = run.updates.size();
  j["update_ms"] = sorted.empty() ? Json{{"mean", nullptr}, {"p99", nullptr}, {"max", nullptr}}
                                  : Json{{"mean", mean_ms}, {"p99", p99_ms}, {"max", max_ms}};
  j["realtime_factor"] = run.realtimeFactor();
  j["online_tracked_share"] = run.online_tracked_share;
  j["initializations"] = run.initializations;
  j["reinitializations"] = run.reinitializations;
  j["standstill_priors"] = run.standstill_priors;
  j["input_dropped"] = inputDroppedJson(run.input_dropped);
  j["init_attempts"] = run.init_attempts;
  j["init_status"] = run.init_status;
  j["last_failure"] = run.last_failure;
  j["position_only_poses"] = run.position_only.size();
  j["first_position_s"] = optionalJson(run.first_position_s);
  j["first_full_state_s"] = optionalJson(run.first_full_state_s);
  j["height_band_in_use"] = run.height_band_in_use;
  j["height_band_note"] = run.height_band_note;
  j["flagged_nlos_excess_m"] = run.flagged_excess_m;
  j["flagged_nlos_scale_m"] = run.flagged_scale_m;
  j["nlos_gap_db"] = run.nlos_gap_db;  // NaN (none learnt) dumps as null
  const NlosClassification& n = run.nlos;
  Json nlos{{"ranges", n.ranges}, {"downweighted", n.downweighted}, {"downweighted_fraction", n.downweightedFraction()}};
  if (n.labelled()) {
    nlos["labelled_nlos"] = n.labelled_nlos;
    nlos["nlos_caught"] = n.nlosCaught();
    nlos["labelled_los"] = n.labelled_los;
    nlos["los_lost"] = n.losLost();
  }
  j["nlos"] = std::move(nlos);
  if (run.ape_online) {
    j["ape_online"] = statsJson(*run.ape_online);
    j["ape_smoothed"] = statsJson(*run.ape_smoothed);
  }
  if (run.covariance_online) j["covariance_online"] = consistencyJson(*run.covariance_online);
  if (run.covariance_position_only) j["covariance_position_only"] = consistencyJson(*run.covariance_position_only);
  std::ofstream summary(dir / "summary.json");
  // Paths are the user's bytes, not necessarily UTF-8: bad bytes become U+FFFD.
  summary << j.dump(2, ' ', false, Json::error_handler_t::replace) << '\n';
  if (!summary) throw std::runtime_error("cannot write " + (dir / "summary.json").string());

  if (o.library_defaults) {
    std::printf("rilo replay: the library's own estimator (lag %g s), device of the recording\n", o.settings.lag_s);
  } else {
    std::printf("rilo replay: estimator of %s (lag %g s), device of the %s\n",
                o.config.empty() ? std::string(kShippedConfigName).c_str() : o.config.c_str(), o.settings.lag_s,
                o.settings.device_from_recording ? "recording where its meta.yaml gives it" : "configuration");
  }
  char times[96] = "update times n/a";
  if (!sorted.empty()) std::snprintf(times, sizeof times, "mean %.2f ms, p99 %.2f ms, max %.2f ms", mean_ms, p99_ms, max_ms);
  std::printf("rilo replay: %s with %s/%s: %zu updates, %s, %.0fx real time, %llu re-initializations, tracking %.0f%% of "
              "the time\n",
              o.recording.c_str(), o.settings.smoother.c_str(), o.settings.noise.c_str(), run.updates.size(), times,
              run.realtimeFactor(), static_cast<unsigned long long>(run.reinitializations), 100.0 * run.online_tracked_share);
  if (run.input_dropped.total() > 0 || run.input_dropped.time_jumps > 0) {
    std::printf("  input screen: dropped %llu rows (%s), %llu IMU time jumps taken\n",
                static_cast<unsigned long long>(run.input_dropped.total()), inputDroppedText(run.input_dropped).c_str(),
                static_cast<unsigned long long>(run.input_dropped.time_jumps));
  }
  if (run.first_position_s) {
    char full[32] = "never";
    if (run.first_full_state_s) std::snprintf(full, sizeof full, "after %.1f s", *run.first_full_state_s);
    std::printf("  first position after %.1f s of data (%zu position-only while initializing), first full state %s\n",
                *run.first_position_s, run.position_only.size(), full);
  }
  {
    const MeasurementCounts& m = run.measurements;
    std::printf("  measurements used (dropped by --reception %.2f):", o.settings.reception);
    for (const auto& [name, c] : {std::pair{"range", m.range}, std::pair{"tdoa", m.tdoa}, std::pair{"ultrasonic", m.ultrasonic}}) {
      if (c.recorded == 0) continue;
      if (!c.selected) {
        std::printf(" %s not selected (%zu recorded);", name, c.recorded);
      } else {
        std::printf(" %s %zu of %zu (%zu);", name, c.used, c.recorded, c.dropped);
        if (c.flagged_one + c.flagged_both > 0) {
          std::printf(" flagged NLOS: one packet %zu, both %zu;", c.flagged_one, c.flagged_both);
        }
        if (c.deep_nlos > 0) std::printf(" dropped as deep NLOS: %zu;", c.deep_nlos);
      }
    }
    std::printf("\n");
  }
  if (!run.height_band_note.empty()) std::printf("  %s\n", run.height_band_note.c_str());
  if (run.initializations == 0) std::printf("  never initialized: %s\n", run.init_status.c_str());
  if (!run.last_failure.empty()) std::printf("  last tracking failure: %s\n", run.last_failure.c_str());
  if (n.ranges > 0) {
    std::printf("  NLOS: %.0f%% of %zu ranges down-weighted (robust weight < 0.5 at the smoothed trajectory)", 100.0 * n.downweightedFraction(), n.ranges);
    if (n.labelled()) std::printf("; of the labelled NLOS %.0f%% caught, of the LOS %.0f%% lost", 100.0 * n.nlosCaught(), 100.0 * n.losLost());
    std::printf("\n");
  }
  if (run.ape_online) {
    for (const auto& [label, e] : {std::pair{"online  ", *run.ape_online}, std::pair{"smoothed", *run.ape_smoothed}}) {
      if (e.ape_3d.count == 0) {
        std::printf("  APE %s n/a (no poses)\n", label);
        continue;
      }
      std::printf("  APE %s mean %.3f m, median %.3f, rmse %.3f, max %.3f (horizontal %.3f, vertical %.3f, height offset %+.3f)\n",
                  label, e.ape_3d.mean, e.ape_3d.median, e.ape_3d.rmse, e.ape_3d.max, e.ape_horizontal.mean,
                  e.ape_vertical.mean, e.vertical_bias_m);
    }
  }
  for (const auto& [label, c] : {std::pair{"online       ", run.covariance_online},
                                  std::pair{"position-only", run.covariance_position_only}}) {
    if (!c || c->poses == 0) continue;
    std::printf("  covariance %s: %.0f%% horizontal / %.0f%% vertical inside its 95%% region (honest: 95%%), "
                "NEES %.1f (3); sigma %.3f / %.3f m against error %.3f / %.3f m (rms per axis)\n",
                label, 100.0 * c->horizontal_in_95, 100.0 * c->vertical_in_95, c->nees_mean, c->sigma_horizontal_m,
                c->sigma_vertical_m, c->error_horizontal_m, c->error_vertical_m);
  }
  std::printf("  wrote %s/{online.tum,%ssmoothed.tum,%scovariance.csv,timing.csv,summary.json}\n", o.out.c_str(),
              run.position_only.empty() ? "" : "position_only.tum,", rec.groundtruth.empty() ? "" : "groundtruth.tum,");
  return 0;
}

void addReplayCommand(CLI::App& app) {
  auto options = std::make_shared<ReplayOptions>();
  CLI::App* cmd = app.add_subcommand("replay", "Run the online pipeline over a recording (as fast as possible) and write its trajectories and timing");
  cmd->add_option("REC", options->recording, "Recording folder")->required()->check(CLI::ExistingDirectory);
  cmd->add_option("--out", options->out, "Output folder (required unless --view)");
  auto view = std::make_shared<ReplayViewOptions>();
  cmd->add_flag("--view", view->enabled,
                "Replay live through the service instead and serve rilo view's page over it (writes no files)");
  cmd->add_option("--view-port", view->port, "With --view: TCP port of the page (0: any free port)")
      ->capture_default_str()
      ->check(cli::notNegative());
  cmd->add_option("--view-speed", view->speed, "With --view: recording seconds per second")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 100.0));
  cmd->add_option("--config", options->config,
                  "rilod configuration (YAML) whose estimator the replay runs: what the service would have published "
                  "on the recording's device (default: the shipped config/rilod.yaml, built in). Options given with "
                  "it override it")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--library-defaults", options->library_defaults,
                "Run the library's own estimator (0.15 m range sigma, 5 s lag) on the recording's device instead of "
                "a configuration: what the replay ran without --config before session 31")
      ->excludes("--config");
  cmd->add_option("--device-from", options->settings.device_from_recording,
                  "The IMU noise densities, lever arms and antennas: recording (those its meta.yaml and "
                  "tags.csv give, the rest the configuration's) or config (the configuration's only)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, bool>{{"recording", true}, {"config", false}}))
      ->option_text("recording|config (default recording)");  // names, not the transformer's numbers
  CLI::Option* smoother = cmd->add_option("--smoother", options->settings.smoother,
                                          "Estimator: an incremental smoother, or the EKF baseline (default: the configuration's smoother)")
      ->check(CLI::IsMember(estimatorNames()));
  CLI::Option* noise = cmd->add_option("--noise", options->settings.noise, "Range noise model (default: the configuration's noise_model)")
      ->check(CLI::IsMember({"gaussian", "huber", "cauchy", "asymmetric"}));
  cmd->add_option("--range-hz", options->settings.range_hz, "Thin ranges to this total rate (Hz; 0 keeps all)")
      ->capture_default_str()->check(CLI::Range(0.0, 1000.0));
  cmd->add_option("--thinning", options->settings.thinning,
                  "Which ranges --range-hz keeps: rotate (the anchor ranged longest ago, as a low-rate tag's scheduler) or first")
      ->transform(CLI::CheckedTransformer(std::map<std::string, RangeThinning>{{"rotate", RangeThinning::kRotate},
                                                                               {"first", RangeThinning::kFirst}}))
      ->option_text("rotate|first (default " + std::string(rangeThinningName(options->settings.thinning)) + ")");
  CLI::Option* lag = cmd->add_option("--lag", options->settings.lag_s, "Fixed lag of the smoother (s; default: the configuration's lag_s)")
      ->check(CLI::Range(0.5, 600.0));
  cmd->add_option("--range-sigma", options->settings.range_sigma_m, "LOS range noise std-dev (m)")->check(CLI::Range(0.001, 10.0));
  cmd->add_option("--nlos-scale", options->settings.nlos_scale_m, "Half-Cauchy scale of the NLOS range excess (m; asymmetric model)")
      ->check(CLI::Range(0.001, 100.0));
  cmd->add_option("--nlos-weight", options->settings.nlos_weight, "Prior NLOS probability (asymmetric model)")
      ->check(CLI::Range(0.001, 0.499));
  cmd->add_option("--nlos-gap-db", options->settings.nlos_power_gap_db,
                  "The receiver's NLOS indicator: ranges whose RX level exceeds the first-path power by more than "
                  "this get the asymmetric model's NLOS component (dB; default 6, Decawave APS006; inf: off)")
      ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  cmd->add_option("--flagged-nlos-weight", options->settings.flagged_nlos_weight,
                  "Prior NLOS probability of a range the receiver flags (--nlos-gap-db), with the mixture "
                  "(--flagged-nlos-component false; default 0.45)")
      ->check(CLI::Range(0.001, 0.499));
  cmd->add_option("--flagged-nlos-component", options->settings.flagged_nlos_component,
                  "Flagged ranges get the asymmetric model's NLOS component alone, shifted by the estimated excess "
                  "(true, the default), or the mixture at --flagged-nlos-weight (false)");
  cmd->add_option("--flagged-nlos-scale", options->settings.flagged_nlos_scale_m,
                  "Half-Cauchy scale of the excess of a range the receiver flags (m; default with the NLOS "
                  "component 1, widened by sqrt(rate / 10 Hz) for faster two-way ranging, at most 20 range sigmas; "
                  "--nlos-scale with the mixture). Given, it also applies to the initializer's batch")
      ->check(CLI::Range(0.001, 100.0));
  cmd->add_option("--flagged-excess-quantile", options->settings.flagged_excess_quantile,
                  "Quantile of the flagged ranges' residuals taken as their excess, estimated on line (default 0.25; 0: "
                  "off, the NLOS component's mode instead)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--los-gap-calibration", options->settings.los_gap_calibration,
                  "Lower the NLOS flag threshold (--nlos-gap-db, an upper bound) to where the ranges' residuals show "
                  "the LOS gaps end, learnt on line (true/false; default true)");
  cmd->add_option("--rx-level-indicator", options->settings.rx_level_indicator,
                  "Where ranges carry the RX level but no first-path power, flag as NLOS those far below the LOS "
                  "path-loss envelope learnt on line (true/false; default true)");
  cmd->add_option("--nlos-memory", options->settings.nlos_memory_s,
                  "Where ranges carry no first-path power, flag as NLOS the next range of an anchor whose last two "
                  "the mixture took as NLOS within this (s; default 0.5; 0: off)")
      ->check(CLI::Range(0.0, 60.0));
  cmd->add_option("--range-error-correlation", options->settings.range_error_correlation_s,
                  "Tracking weighs each two-way range by one over its anchor's ranges within this time, over which "
                  "they share one error (s; default 0: off, every range counts alone; docs/noise-models.md, session 44)")
      ->check(CLI::Range(0.0, 60.0));
  cmd->add_option("--max-outside-anchors", options->settings.max_outside_anchors_m,
                  "Re-initialize when the tag is estimated farther than this beyond the anchors' horizontal box while "
                  "ranging holds it (m; default 10; inf: off)")
      ->check(CLI::Range(0.001, std::numeric_limits<double>::infinity()));
  cmd->add_option("--init-max-outside-anchors", options->settings.init_max_outside_anchors_m,
                  "Start-up refuses a solution whose tag lies farther than this beyond the anchors' horizontal box, a "
                  "mirror of the truth behind a wall of anchors (m; default 1; inf: off)")
      ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  cmd->add_option("--init-heavy-nlos-after", options->settings.init_heavy_nlos_after_s,
                  "Start-up accepts costs up to twice its gates when few two-way ranges are shorter than the solution "
                  "predicts (heavy NLOS, not bad data) this long after the first two-way range (s of data; default 60; 0: at once; "
                  "inf: off)")
      ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  cmd->add_option("--height-band", options->settings.height_band, "Soft tag height band on tracked states (true/false)");
  cmd->add_option("--floor-z", options->settings.floor_z_m, "Floor height in the anchors' frame (m)");
  cmd->add_option("--min-height", options->settings.min_height_m, "Lowest tag height above the floor (m)");
  cmd->add_option("--max-height", options->settings.max_height_m, "Highest tag height above the floor (m)");
  cmd->add_option("--range-lever", options->settings.range_lever,
                  "Two-way ranges speak to the height only by their vertical lever (true/false; default: the "
                  "configuration's height_band.range_lever)");
  cmd->add_option("--height-hold-sigma", options->settings.height_hold_sigma_m,
                  "Each state's height held towards the carry height, m per sqrt(s) of data (0 = off; default: the "
                  "configuration's height_band.hold_sigma_m)")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--learn-carry-height", options->settings.learn_carry_height,
                  "Learn the carry height from where ranges tell the height (true/false; default: the "
                  "configuration's height_band.learn_carry_height)");
  cmd->add_option("--vertical-speed-sigma", options->settings.vertical_speed_sigma_m_s,
                  "Std-dev of a zero vertical-speed prior per vertical_speed_correlation_s of states (m/s; 0 = none; default: the configuration's vertical_speed_sigma_m_s, whose auto is 0.016 when TDoA rows are used, else 0.1)")->check(CLI::Range(0.0, 100.0));
  cmd->add_option("--zero-velocity-sigma", options->settings.zero_velocity_sigma_m_s,
                  "Std-dev of a zero-velocity prior on each state the IMU shows still (m/s per second still; 0 = none; "
                  "default: the configuration's zero_velocity_sigma_m_s)")
      ->check(CLI::Range(0.0, 100.0));
  cmd->add_option_function<std::string>(
         "--measurements", [options](const std::string& list) { options->settings.measurements = measurementKindsFromString(list); },
         "Measurement kinds fed to the pipeline, comma-separated: range,tdoa,ultrasonic (default: every kind the recording has)")
      ->check([](const std::string& list) {
        try {
          (void)measurementKindsFromString(list);
          return std::string();
        } catch (const std::invalid_argument& e) {
          return std::string(e.what());
        }
      });
  cmd->add_option("--reception", options->settings.reception,
                  "Fraction of UWB packets received (0..1): each TDoA epoch and each range kept with this probability (seeded)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--reception-seed", options->settings.reception_seed, "Seed of the --reception draws")
      ->capture_default_str()
      ->check(cli::notNegative());
  cmd->add_option("--state-window-ms", options->settings.same_state_window_ms,
                  "Measurements closer than this share one state, whatever the data (ms; default: the configuration's range.same_state_window_s, and tdoa.state_window_s once the data hold TDoA rows)")
      ->check(CLI::Range(0.0, 1000.0));
  cmd->add_option("--tdoa-sigma", options->settings.tdoa_sigma_m, "LOS std-dev of a TDoA range difference (m)")
      ->check(CLI::Range(0.001, 10.0));
  cmd->add_option("--ultrasonic-sigma", options->settings.ultrasonic_sigma_m, "LOS std-dev of an ultrasonic range (m)")
      ->check(CLI::Range(0.0001, 10.0));
  cmd->add_option("--tdoa-noise", options->settings.tdoa_noise, "TDoA noise model (default huber)")
      ->check(CLI::IsMember(rangeLossNames()));
  cmd->add_option("--ultrasonic-noise", options->settings.ultrasonic_noise, "Ultrasonic noise model (default huber)")
      ->check(CLI::IsMember(rangeLossNames()));
  cmd->add_option("--tdoa-nlos-indicator", options->settings.tdoa_nlos_indicator,
                  "Use the TDoA rows' receive diagnostics (rssi/fp columns of tdoa.csv): a packet whose RX level "
                  "minus first-path power exceeds the NLOS gap is flagged (true/false; default true)");
  cmd->add_option("--tdoa-flagged-noise", options->settings.tdoa_flagged_noise,
                  "Loss of a TDoA row with one packet flagged, oriented so the flagged path is the long side "
                  "(default asymmetric)")
      ->check(CLI::IsMember(rangeLossNames()));
  cmd->add_option("--tdoa-both-flagged-factor", options->settings.tdoa_both_flagged_factor,
                  "Sigma factor of a TDoA row with both packets flagged (default 3)")
      ->check(CLI::Range(1.0, 100.0));
  cmd->add_option("--tdoa-one-flagged-factor", options->settings.tdoa_one_flagged_factor,
                  "EKF: sigma factor of a TDoA row with one packet flagged (default 2)")
      ->check(CLI::Range(1.0, 100.0));
  cmd->add_option("--tdoa-max-gap-db", options->settings.tdoa_max_power_gap_db,
                  "TDoA rows with a packet whose RX level minus first-path power exceeds this are not used: deep NLOS "
                  "(dB; default 15; inf: all used; needs --tdoa-nlos-indicator, rows without diagnostics are kept)")
      ->check(CLI::Range(0.0, std::numeric_limits<double>::infinity()));
  cmd->add_option("--tdoa-gap-excess", options->settings.tdoa_gap_excess,
                  "Learn each TDoA packet's NLOS excess per RX-level-minus-first-path gap bin from the rows' residuals "
                  "and take it off the rows (true/false; default true; graph estimators; needs --tdoa-nlos-indicator)");
  cmd->add_option("--dynamic-covariance", options->settings.dynamic_covariance,
                  "Per-link TDoA/ultrasonic sigmas from their residuals (true/false; default: on once the data hold TDoA "
                  "rows; the configuration's tdoa.dynamic_covariance)");
  cmd->callback([options, smoother, noise, lag, view] {
    int code = 1;
    try {
      const GivenOptions given{smoother->count() > 0, noise->count() > 0, lag->count() > 0};
      if (options->library_defaults) {
        if (!options->settings.device_from_recording) {
          throw std::invalid_argument("--library-defaults has no configuration to take the device from (--device-from config)");
        }
      } else if (options->config.empty()) {
        applyShippedConfig(given, options->settings);
      } else {
        applyServiceConfig(options->config, given, options->settings);
      }
      if (view->enabled) {
        code = runReplayView(*options, *view);
      } else {
        if (options->out.empty()) throw std::invalid_argument("--out is required (unless --view)");
        code = runReplay(*options);
      }
    } catch (const std::exception& e) {
      spdlog::error("{}", e.what());
    }
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
