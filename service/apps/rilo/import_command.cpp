#include "import_command.h"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "hal/recording/number_text.h"
#include "hal/recording/recording_files.h"
#include "import/physics_check.h"
#include "import/util_import.h"

namespace rilo::tool {
namespace {

double parseNumber(const std::string& option, const std::string& text) {
  double v = 0.0;
  if (recording::parseDouble(text, v) != recording::NumberStatus::kOk) {
    throw std::invalid_argument(option + ": '" + text + "' is not a number");
  }
  return v;
}

Vec3 parseLeverArm(const std::string& text) {
  Vec3 v;
  std::size_t start = 0;
  for (int i = 0; i < 3; ++i) {
    const std::size_t comma = text.find(',', start);
    if ((i < 2) != (comma != std::string::npos)) {
      throw std::invalid_argument("--lever-arm: expected three numbers x,y,z (m), got '" + text + "'");
    }
    v(i) = parseNumber("--lever-arm", text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    start = comma + 1;
  }
  return v;
}

template <typename T>
T parseChoice(std::optional<T> (*parse)(std::string_view), const std::string& option, const std::string& text,
              const char* choices) {
  const std::optional<T> v = parse(text);
  if (!v) throw std::invalid_argument(option + ": '" + text + "' is not one of " + choices);
  return *v;
}

importer::UtilImportOptions importOptions(const ImportUtilOptions& o) {
  importer::UtilImportOptions u;
  u.tdoa_sign = parseChoice(importer::tdoaSignFromString, "--tdoa-sign", o.tdoa_sign, "b-minus-a, a-minus-b");
  u.accel_unit = parseChoice(importer::accelUnitFromString, "--accel-unit", o.accel_unit, "g, m/s2");
  u.gyro_unit = parseChoice(importer::gyroUnitFromString, "--gyro-unit", o.gyro_unit, "deg/s, rad/s");
  u.imu_clock = parseChoice(importer::imuClockFromString, "--imu-clock", o.imu_clock, "gyro, accel");
  if (!o.lever_arm.empty()) u.lever_arm_m = parseLeverArm(o.lever_arm);
  u.gravity_m_s2 = parseNumber("--gravity", o.gravity);
  if (!(u.gravity_m_s2 > 1.0 && u.gravity_m_s2 < 20.0)) {
    throw std::invalid_argument("--gravity must be in (1, 20) m/s^2, got " + o.gravity);
  }
  const double gap_ms = parseNumber("--max-imu-gap-ms", o.max_imu_gap_ms);
  if (!(gap_ms > 0.0 && gap_ms <= 1e4)) {
    throw std::invalid_argument("--max-imu-gap-ms must be in (0, 1e4] ms, got " + o.max_imu_gap_ms);
  }
  u.max_imu_gap_s = gap_ms * 1e-3;
  u.drop_unordered = o.drop_unordered;
  return u;
}

int importUtil(const ImportUtilOptions& o) {
  if (o.out.empty() && !o.check_only) throw std::invalid_argument("--out is required (or --check to write nothing)");
  if (!o.check_only && !o.overwrite) {
    // Fail before parsing, and say how to proceed (the writer would refuse too).
    for (const std::string_view name : {recording::kMetaFile, recording::kAnchorsFile, recording::kImuFile}) {
      if (std::filesystem::exists(std::filesystem::path(o.out) / name)) {
        throw std::invalid_argument(o.out + " already holds a recording (" + std::string(name) +
                                    "): --overwrite to replace it");
      }
    }
  }
  const importer::UtilImportOptions options = importOptions(o);
  const importer::UtilImport imported = importer::importUtil(o.flight, o.anchors, options);
  importer::PhysicsCheckParams params;
  params.max_imu_gap_s = options.max_imu_gap_s;
  const importer::PhysicsCheck check = importer::checkPhysics(imported.recording, params);
  const std::vector<importer::CheckVerdict> verdicts = importer::judgeUtilPhysics(check, options);
  std::printf("rilo import-util: %s", importer::formatUtilSummary(imported, check, verdicts).c_str());

  const bool contradiction = importer::anyContradiction(verdicts);
  if (contradiction && !o.ignore_check) {
    std::fflush(stdout);
    spdlog::error("the data contradicts the chosen options (CONTRADICTS above): {}; change the option as suggested, "
                  "or --ignore-check to write anyway",
                  o.check_only ? "check failed" : "nothing written");
    return 2;
  }
  if (o.check_only) {
    std::printf("  check only: nothing written\n");
    return 0;
  }
  importer::writeUtilRecording(imported, o.out, o.overwrite);
  std::printf("  wrote %s (%zu imu, %zu tdoa, %zu ground-truth rows)%s\n", o.out.c_str(),
              imported.recording.imu.size(), imported.recording.tdoa.size(), imported.recording.groundtruth.size(),
              contradiction ? " DESPITE the contradiction (--ignore-check)" : "");
  return 0;
}

}  // namespace

int runImportUtil(const ImportUtilOptions& options) {
  try {
    return importUtil(options);
  } catch (const std::exception& e) {
    std::fflush(stdout);
    spdlog::error("{}", e.what());
    return 1;
  }
}

void addImportUtilCommand(CLI::App& app) {
  auto options = std::make_shared<ImportUtilOptions>();
  CLI::App* cmd = app.add_subcommand(
      "import-util", "Convert a UTIL dataset flight (UTIAS UWB TDoA, Crazyflie) into a recording folder");
  cmd->add_option("FLIGHT", options->flight, "Flight CSV of the dataset (csv-data/constN/constN-trialM-tdoaK.csv)")
      ->required();
  cmd->add_option("--anchors", options->anchors,
                  "Anchor survey of the flight's constellation (survey-results/anchor_constN_survey.txt)")
      ->required();
  cmd->add_option("--out", options->out, "Recording folder to write (required unless --check)");
  cmd->add_option("--tdoa-sign", options->tdoa_sign,
                  "Meaning of tdoa_meas: b-minus-a = |p-A_idB| - |p-A_idA| (the dataset's), a-minus-b = the opposite")
      ->capture_default_str();
  cmd->add_option("--accel-unit", options->accel_unit, "Unit of acc_x..z in the file: g or m/s2")->capture_default_str();
  cmd->add_option("--gyro-unit", options->gyro_unit, "Unit of gyro_x..z in the file: deg/s or rad/s")
      ->capture_default_str();
  cmd->add_option("--imu-clock", options->imu_clock,
                  "IMU samples at the gyro or the accel times; the other stream is interpolated linearly")
      ->capture_default_str();
  cmd->add_option("--lever-arm", options->lever_arm,
                  "UWB antenna in the body frame, x,y,z (m); default the dataset's -0.01245,0.00127,0.0908");
  cmd->add_option("--gravity", options->gravity, "g (m/s^2) for the g -> m/s^2 conversion and meta.yaml")
      ->capture_default_str();
  cmd->add_option("--max-imu-gap-ms", options->max_imu_gap_ms,
                  "No interpolation between samples further apart: the IMU sample is dropped and counted")
      ->capture_default_str();
  cmd->add_flag("--drop-unordered", options->drop_unordered,
                "Drop and count samples out of time order instead of failing");
  cmd->add_flag("--overwrite", options->overwrite, "Replace a recording already in --out");
  cmd->add_flag("--check", options->check_only, "Parse and run the physics check only; write nothing");
  cmd->add_flag("--ignore-check", options->ignore_check, "Write even if the physics check contradicts the chosen options");
  cmd->footer(
      "Physics check (always run, on the converted data against the Vicon ground truth): median |accel| against g\n"
      "(g vs m/s^2), gyro integral against the Vicon rotation over 0.25 s windows (deg/s vs rad/s), and TDoA\n"
      "residuals with the chosen and the opposite sign; with the chosen sign, a fit of a lever-arm correction and\n"
      "per-pair constant biases is reported when evident. A contradiction fails with exit code 2 and names the\n"
      "option to change. Exit code 1 on bad input, with file:line: column in the message. See docs/util-dataset.md.");
  cmd->callback([options] {
    const int code = runImportUtil(*options);
    if (code != 0) throw CLI::RuntimeError(code);
  });
}

}  // namespace rilo::tool
