#include "eval_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "evaluation/tum.h"
#include "hal/recording/number_text.h"
#include "hal/recording/recording_files.h"
#include "hal/recording/recording_reader.h"

namespace rilo::tool {

namespace {

using Json = nlohmann::ordered_json;

/// {"mean": .., "median": .., "rmse": .., "max": .., "count": n}; null figures when count is 0.
Json jsonStats(const ErrorStats& s) {
  const auto fig = [&](double v) { return s.count > 0 ? Json(v) : Json(nullptr); };
  return Json{{"mean", fig(s.mean)}, {"median", fig(s.median)}, {"rmse", fig(s.rmse)}, {"max", fig(s.max)},
              {"count", s.count}};
}

Json jsonRpe(const RelativePoseErrorStats& r, const char* delta_key) {
  return Json{{delta_key, r.params.delta},
              {"pairs", r.translation_m.count},
              {"translation_m", jsonStats(r.translation_m)},
              {"rotation_deg", jsonStats(r.rotation_deg)}};
}

std::string shortNumber(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

double seconds(std::int64_t t_ns) { return static_cast<double>(t_ns) * 1e-9; }

void printStatsRow(const char* label, const ErrorStats& s) {
  if (s.count == 0) {
    std::printf("  %-22s %9s %9s %9s %9s %8d\n", label, "-", "-", "-", "-", 0);
    return;
  }
  std::printf("  %-22s %9.4f %9.4f %9.4f %9.4f %8zu\n", label, s.mean, s.median, s.rmse, s.max, s.count);
}

void checkOptions(const EvalOptions& o) {
  if (!o.option_error.empty()) throw std::invalid_argument(o.option_error);
  if (!(o.max_dt_ms >= 0.0 && o.max_dt_ms <= 1e6)) {
    throw std::invalid_argument("--max-dt-ms must be in [0, 1e6] ms, got " + std::to_string(o.max_dt_ms));
  }
  if (!(o.rpe_delta_s > 0.0 && o.rpe_delta_s <= 1e6)) {
    throw std::invalid_argument("--rpe-delta-s must be in (0, 1e6] s, got " + std::to_string(o.rpe_delta_s));
  }
  if (!(o.rpe_delta_m > 0.0 && o.rpe_delta_m <= 1e6)) {
    throw std::invalid_argument("--rpe-delta-m must be in (0, 1e6] m, got " + std::to_string(o.rpe_delta_m));
  }
}

void printEvaluation(const EvalOptions& o, const TrajectoryEvaluation& ev, const TumTrajectory& estimate) {
  const auto& assoc = ev.association;
  std::printf("rilo eval: %s against the ground truth of %s\n", o.estimate.c_str(), o.recording.c_str());
  std::printf("  poses: %zu estimated, %zu matched to ground truth within %g ms (largest offset %.1f ms), %zu without\n",
              ev.estimate_poses, assoc.pairs.size(), o.max_dt_ms, static_cast<double>(assoc.max_abs_dt_ns) * 1e-6,
              assoc.unmatched.size());
  if (!assoc.unmatched.empty()) {
    std::printf("  warning: %zu poses (first at %.3f s, last at %.3f s) have no ground truth within %g ms and are not "
                "in the figures\n",
                assoc.unmatched.size(), seconds(estimate[assoc.unmatched.front()].t_ns),
                seconds(estimate[assoc.unmatched.back()].t_ns), o.max_dt_ms);
  }
  std::printf("  %-22s %9s %9s %9s %9s %8s\n", "", "mean", "median", "rmse", "max", "n");
  printStatsRow("APE 3D (m)", ev.ape.ape_3d);
  printStatsRow("APE horizontal (m)", ev.ape.ape_horizontal);
  printStatsRow("APE vertical (m)", ev.ape.ape_vertical);
  std::printf("  %-22s %+9.4f\n", "height offset (m)", ev.ape.vertical_bias_m);
  char label[64];
  std::snprintf(label, sizeof label, "RPE %g s trans (m)", ev.rpe_time.params.delta);
  printStatsRow(label, ev.rpe_time.translation_m);
  std::snprintf(label, sizeof label, "RPE %g s rot (deg)", ev.rpe_time.params.delta);
  printStatsRow(label, ev.rpe_time.rotation_deg);
  std::snprintf(label, sizeof label, "RPE %g m trans (m)", ev.rpe_distance.params.delta);
  printStatsRow(label, ev.rpe_distance.translation_m);
  std::snprintf(label, sizeof label, "RPE %g m rot (deg)", ev.rpe_distance.params.delta);
  printStatsRow(label, ev.rpe_distance.rotation_deg);
  if (ev.rpe_distance.translation_m.count == 0) {
    std::printf("  (no pose pair %g m apart along the ground truth: the trajectory is too short for this RPE)\n",
                ev.rpe_distance.params.delta);
  }
}

int evaluate(const EvalOptions& o) {
  checkOptions(o);
  const TumTrajectory estimate = readTum(o.estimate);
  if (estimate.empty()) throw std::runtime_error(o.estimate + ": no poses in the file");
  const Recording rec = readRecording(o.recording);
  if (rec.groundtruth.empty()) {
    throw std::runtime_error(o.recording + ": the recording has no ground truth (" +
                             std::string(recording::kGroundTruthFile) + " missing or empty)");
  }
  EvaluationParams params;
  params.max_dt_ns = std::llround(o.max_dt_ms * 1e6);
  params.rpe_time.delta = o.rpe_delta_s;
  params.rpe_distance.delta = o.rpe_delta_m;
  const TrajectoryEvaluation ev = evaluateTrajectory(estimate, rec.groundtruth, params);
  if (ev.association.pairs.empty()) {
    char detail[256];
    std::snprintf(detail, sizeof detail,
                  "no estimated pose has ground truth within %g ms: the estimate spans %.3f..%.3f s, the ground "
                  "truth %.3f..%.3f s (same clock? both must be in recording time)",
                  o.max_dt_ms, seconds(estimate.front().t_ns), seconds(estimate.back().t_ns),
                  seconds(rec.groundtruth.front().t_ns), seconds(rec.groundtruth.back().t_ns));
    throw std::runtime_error(detail);
  }
  printEvaluation(o, ev, estimate);
  if (!o.json.empty()) {
    std::ofstream out(o.json, std::ios::binary | std::ios::trunc);
    out << evaluationJson(o, ev);
    out.flush();
    if (!out) throw std::runtime_error("cannot write " + o.json);
    std::printf("  wrote %s\n", o.json.c_str());
  }
  return 0;
}

}  // namespace

std::string evaluationJson(const EvalOptions& o, const TrajectoryEvaluation& ev) {
  const auto& assoc = ev.association;
  Json j;
  j["estimate"] = o.estimate;
  j["recording"] = o.recording;
  j["max_dt_ms"] = o.max_dt_ms;
  j["poses"] = Json{{"estimated", ev.estimate_poses},
                    {"matched", assoc.pairs.size()},
                    {"unmatched", assoc.unmatched.size()},
                    {"ground_truth", ev.truth_poses},
                    {"max_abs_dt_ms", static_cast<double>(assoc.max_abs_dt_ns) * 1e-6}};
  j["ape_m"] = Json{{"3d", jsonStats(ev.ape.ape_3d)},
                    {"horizontal", jsonStats(ev.ape.ape_horizontal)},
                    {"vertical", jsonStats(ev.ape.ape_vertical)},
                    {"vertical_bias", ev.ape.vertical_bias_m}};
  j["rpe_time"] = jsonRpe(ev.rpe_time, "delta_s");
  j["rpe_distance"] = jsonRpe(ev.rpe_distance, "delta_m");
  // Paths are the user's bytes, not necessarily UTF-8: bad bytes become U+FFFD.
  return j.dump(2, ' ', false, Json::error_handler_t::replace) + "\n";
}

int runEval(const EvalOptions& options) {
  try {
    return evaluate(options);
  } catch (const std::exception& e) {
    std::fflush(stdout);
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addEvalCommand(CLI::App& app) {
  auto options = std::make_shared<EvalOptions>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Accuracy of an estimated trajectory (TUM file) against a recording's ground truth: APE and RPE");
  cmd->add_option("EST", options->estimate, "Estimated trajectory, TUM format (t x y z qx qy qz qw), e.g. smoothed.tum")
      ->required();
  cmd->add_option("REC", options->recording, "Recording folder whose groundtruth.csv is the reference")->required();
  cmd->add_option("--json", options->json, "Also write the figures as JSON to this file");
  // Numbers are parsed here, not by CLI11, so that a malformed value is bad
  // input with exit code 1 like every other (CLI11 would exit with 104).
  const auto addNumber = [&](const std::string& name, double EvalOptions::*member, const std::string& help) {
    const double default_value = (*options).*member;
    cmd->add_option_function<std::string>(
           name,
           [options, name, member](const std::string& text) {
             double value = 0.0;
             if (recording::parseDouble(text, value) == recording::NumberStatus::kOk) {
               (*options).*member = value;
             } else if (options->option_error.empty()) {
               options->option_error = name + ": '" + text + "' is not a number";
             }
           },
           help)
        ->type_name("FLOAT")
        ->default_str(shortNumber(default_value));
  };
  addNumber("--max-dt-ms", &EvalOptions::max_dt_ms,
            "Association tolerance: each estimated pose is paired with the ground-truth pose nearest in time if "
            "within this many ms; poses without a partner are counted and reported");
  addNumber("--rpe-delta-s", &EvalOptions::rpe_delta_s, "Time delta of the time-based RPE (s)");
  addNumber("--rpe-delta-m", &EvalOptions::rpe_delta_m,
            "Travelled distance (along the ground truth) of the distance-based RPE (m)");
  cmd->footer(
      "APE: |p_est - p_true| in 3D, horizontally (xy) and vertically (z); no alignment (the anchors fix the frame).\n"
      "Height offset: the mean of (p_est - p_true)_z (m), signed: a vertical error that is an offset, not noise.\n"
      "RPE: for pose pairs (i, j) a delta apart (every pose starts a pair; the partner's separation within 10% of\n"
      "the delta), translation |(T_true_i^-1 T_true_j).p - (T_est_i^-1 T_est_j).p| (m) and the rotation angle of\n"
      "(T_true_i^-1 T_true_j)^-1 (T_est_i^-1 T_est_j) (deg): evo's relative-pose-delta convention.\n"
      "Exit code 1 with a message on bad input (malformed TUM line, unreadable recording, no ground truth, no match).");
  cmd->callback([options] {
    const int code = runEval(*options);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
