// `rilo replay` on the committed demo recording: the tool runs the online
// pipeline and writes the files the issue 4 evaluation reads.
#include <gtest/gtest.h>

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "hal/recording/recording_reader.h"
#include "service_test_support.h"
#include "support/json_file.h"

namespace rilo {
namespace {

std::vector<std::vector<double>> readTum(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<double> row;
    double v = 0.0;
    while (fields >> v) row.push_back(v);
    rows.push_back(row);
  }
  return rows;
}

/// How runRilo runs the child: where its output goes, and an address-space cap.
struct RunOptions {
  std::string stdout_file, stderr_file;  ///< empty: inherited
  bool cap_4gb = false;                  ///< RLIMIT_AS of 4 GB (not under sanitizers: their shadow memory)
};

/// Runs `rilo args...`; returns the exit code (-1 if it did not exit).
int runRilo(const std::vector<std::string>& args, const RunOptions& run = {}) {
  const std::string exe = (testing::binaryDir() / "rilo").string();
  std::vector<char*> argv{const_cast<char*>(exe.c_str())};
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    if (!run.stdout_file.empty() && std::freopen(run.stdout_file.c_str(), "w", stdout) == nullptr) ::_exit(126);
    if (!run.stderr_file.empty() && std::freopen(run.stderr_file.c_str(), "w", stderr) == nullptr) ::_exit(126);
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
    if (run.cap_4gb) {
      const rlimit cap{4ull << 30, 4ull << 30};
      ::setrlimit(RLIMIT_AS, &cap);
    }
#endif
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

/// Replaces data row `row` (1 = the first after the header) of a CSV file.
void replaceRow(const std::filesystem::path& file, std::size_t row, const std::string& text) {
  std::ifstream in(file);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  ASSERT_LT(row, lines.size());
  lines[row] = text;
  std::ofstream out(file, std::ios::trunc);
  for (const std::string& line : lines) out << line << '\n';
}

/// The stamp (first field) of data row `row`.
std::string stampOfRow(const std::filesystem::path& file, std::size_t row) {
  std::ifstream in(file);
  std::string line;
  for (std::size_t i = 0; i <= row && std::getline(in, line); ++i) {
  }
  return line.substr(0, line.find(','));
}

TEST(RiloReplay, ImpossibleRowsAreDroppedAndCountedUnderAMemoryCap) {
  // Issue 37: one range row 28 years ahead grew the replay to 23 GB; ranges
  // of -5, 0 and 1e9 m and an acceleration of 1e30 m/s^2 were fused. Under a
  // 4 GB address-space cap the replay now ends normally and says what it dropped.
  testing::TempDir dir("rilo-replay-screen");
  const std::filesystem::path rec = dir / "rec";
  std::filesystem::copy(testing::sourceDir() / "tests" / "data" / "office-demo", rec);
  const std::filesystem::path ranges = rec / "range.csv";
  const std::filesystem::path imu = rec / "imu.csv";
  replaceRow(ranges, 300, stampOfRow(ranges, 300) + ",1,-5.0,0,,,");
  replaceRow(ranges, 301, stampOfRow(ranges, 301) + ",2,0.0,0,,,");
  replaceRow(ranges, 302, stampOfRow(ranges, 302) + ",3,1000000000.0,0,,,");
  replaceRow(imu, 9000, stampOfRow(imu, 9000) + ",0,0,0,1e30,0,9.81");
  {
    std::ofstream out(ranges, std::ios::app);
    out << "900000000000000000,1,3.0,0,,,\n";
  }
  ASSERT_EQ(runRilo({"replay", rec.string(), "--out", (dir / "out").string()}, RunOptions{"", "", true}), 0)
      << "killed, or out of memory under the 4 GB cap";
  nlohmann::json summary = testing::readJsonFile(dir / "out" / "summary.json");
  EXPECT_EQ(summary["input_dropped"]["far_future"], 1) << summary;
  EXPECT_EQ(summary["input_dropped"]["out_of_bounds"], 3) << summary;
  EXPECT_EQ(summary["input_dropped"]["beyond_full_scale"], 1) << summary;
  EXPECT_EQ(summary["reinitializations"], 0) << summary;
  EXPECT_LT(summary["ape_online"]["mean_m"].get<double>(), 1.0) << summary;  // the estimate never saw them
}

TEST(RiloReplay, NothingEstimatedIsNullInTheSummaryAndNotAvailableOnTheConsole) {
  // Issue 37: with no pose, "APE online mean 0.000 m" and "mean_m": 0 read as
  // a perfect result. Half a second of data gives no pose at all (the first
  // position-only fix needs 3 s).
  testing::TempDir dir("rilo-replay-empty");
  const std::filesystem::path rec = dir / "rec";
  std::filesystem::copy(testing::sourceDir() / "tests" / "data" / "office-demo", rec);
  for (const char* name : {"imu.csv", "range.csv", "groundtruth.csv"}) {
    std::ifstream in(rec / name);
    std::vector<std::string> kept;
    for (std::string line; std::getline(in, line);) {
      if (kept.empty() || std::strtoll(line.c_str(), nullptr, 10) < 1'500'000'000) kept.push_back(line);
    }
    in.close();
    std::ofstream out(rec / name, std::ios::trunc);
    for (const std::string& line : kept) out << line << '\n';
  }
  const std::string console = (dir / "console.txt").string();
  ASSERT_EQ(runRilo({"replay", rec.string(), "--out", (dir / "out").string()}, RunOptions{console, "", false}), 0);
  std::stringstream text;
  text << std::ifstream(console).rdbuf();
  nlohmann::json summary = testing::readJsonFile(dir / "out" / "summary.json");
  EXPECT_EQ(summary["ape_online"]["poses"], 0) << summary;
  for (const char* figure : {"mean_m", "median_m", "rmse_m", "max_m", "vertical_bias_m"}) {
    EXPECT_TRUE(summary["ape_online"][figure].is_null()) << figure << ": " << summary;
    EXPECT_TRUE(summary["ape_smoothed"][figure].is_null()) << figure << ": " << summary;
  }
  for (const char* figure : {"mean", "p99", "max"}) EXPECT_TRUE(summary["update_ms"][figure].is_null()) << summary;
  EXPECT_NE(text.str().find("APE online   n/a (no poses)"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("0 updates, update times n/a"), std::string::npos) << text.str();
}

TEST(RiloReplay, TheReadersWarningsArePrintedOnceWithFileAndLine) {
  // Issue 37: rilo replay hid them (a duplicate row, an unknown meta key).
  testing::TempDir dir("rilo-replay-warnings");
  const std::filesystem::path rec = dir / "rec";
  std::filesystem::copy(testing::sourceDir() / "tests" / "data" / "office-demo", rec);
  {
    std::ifstream in(rec / "imu.csv");
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    in.close();
    lines.insert(lines.begin() + 5, lines[4]);  // data row 4 twice: file lines 5 and 6
    std::ofstream out(rec / "imu.csv", std::ios::trunc);
    for (const std::string& line : lines) out << line << '\n';
  }
  std::ofstream(rec / "meta.yaml", std::ios::app) << "bogus_key: 3\n";
  const std::string errors = (dir / "stderr.txt").string();
  ASSERT_EQ(runRilo({"replay", rec.string(), "--out", (dir / "out").string()}, RunOptions{"", errors, false}), 0);
  std::stringstream text;
  text << std::ifstream(errors).rdbuf();
  const std::string e = text.str();
  const std::string duplicate = "warning: " + (rec / "imu.csv").string() + ":6: column 't_ns': duplicate of line 5 skipped";
  EXPECT_NE(e.find(duplicate), std::string::npos) << e;
  EXPECT_EQ(e.find(duplicate), e.rfind(duplicate)) << "printed twice: " << e;
  EXPECT_NE(e.find("key 'bogus_key': unknown key ignored"), std::string::npos) << e;
}

TEST(RiloReplay, WritesTrajectoriesTimingAndSummary) {
  testing::TempDir out("rilo-replay");
  const std::string exe = (testing::binaryDir() / "rilo").string();
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  const std::string dir = out.path().string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl(exe.c_str(), exe.c_str(), "replay", rec.c_str(), "--out", dir.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  ASSERT_EQ(WEXITSTATUS(status), 0);

  const auto online = readTum(out / "online.tum");
  const auto smoothed = readTum(out / "smoothed.tum");
  ASSERT_GT(online.size(), 400u);  // 45 s at 40 Hz in 50 ms states (over 10 a second), after a ~10 s initialization
  ASSERT_GE(smoothed.size(), online.size());
  for (const auto& row : smoothed) ASSERT_EQ(row.size(), 8u);
  for (std::size_t i = 1; i < smoothed.size(); ++i) ASSERT_GT(smoothed[i][0], smoothed[i - 1][0]);
  // The truth as TUM beside them, for evo: every ground-truth row, same pose.
  const auto truth = readTum(out / "groundtruth.tum");
  const Recording recording = readRecording(rec);
  ASSERT_EQ(truth.size(), recording.groundtruth.size());
  const GroundTruthPose& g = recording.groundtruth[recording.groundtruth.size() / 2];
  const auto& mid = truth[recording.groundtruth.size() / 2];
  EXPECT_NEAR(mid[0], static_cast<double>(g.t_ns) * 1e-9, 1e-9);
  EXPECT_NEAR(mid[1], g.p_w_b.x(), 1e-6);
  EXPECT_NEAR(mid[3], g.p_w_b.z(), 1e-6);
  EXPECT_NEAR(std::abs(mid[7]), std::abs(g.q_w_b.w()), 1e-8);  // TUM: qx qy qz qw
  for (const auto& row : online) {
    const double qn = row[4] * row[4] + row[5] * row[5] + row[6] * row[6] + row[7] * row[7];
    ASSERT_NEAR(qn, 1.0, 1e-6);
  }
  nlohmann::json text = testing::readJsonFile(out / "summary.json");
  EXPECT_TRUE(text.contains("ape_online"));
  EXPECT_TRUE(text.contains("ape_smoothed"));
  EXPECT_EQ(text["reinitializations"], 0) << text;
  // What the service publishes: position-only fixes from the first second
  // (position_only.tum: their orientation is unknown), then the full states
  // (online.tum, strictly increasing times as `rilo eval` needs).
  const double first_position_s = text["first_position_s"].get<double>();
  const double first_full_state_s = text["first_full_state_s"].get<double>();
  EXPECT_LE(first_position_s, 3.0) << text;
  EXPECT_LT(first_position_s, first_full_state_s) << text;
  const auto position_only = readTum(out / "position_only.tum");
  ASSERT_FALSE(position_only.empty());
  EXPECT_EQ(text["position_only_poses"], position_only.size()) << text;
  for (std::size_t i = 1; i < position_only.size(); ++i) ASSERT_GT(position_only[i][0], position_only[i - 1][0]);
  for (std::size_t i = 1; i < online.size(); ++i) ASSERT_GT(online[i][0], online[i - 1][0]);
  // rilo eval reads the online trajectory as it did before.
  EXPECT_EQ(runRilo({"eval", (out / "online.tum").string(),
                     (testing::sourceDir() / "tests" / "data" / "office-demo").string(), "--json",
                     (out / "eval.json").string()}),
            0);
  std::ifstream timing(out / "timing.csv");
  std::string header;
  std::getline(timing, header);
  EXPECT_EQ(header, "t_s,update_ms,cliques_reeliminated,variables_relinearized,tries,accepted,lambda,"
            "cliques_back_substituted,factors_linearized,variables_marginalized,cliques_total");
  // What was published with each pose: its position covariance, one row per
  // fix and per online pose, in time order, symmetric positive diagonal;
  // the summary says how much of the error it covers.
  std::ifstream cov(out / "covariance.csv");
  std::getline(cov, header);
  EXPECT_EQ(header, "t_s,x_m,y_m,z_m,cov_xx,cov_xy,cov_xz,cov_yy,cov_yz,cov_zz,position_only");
  std::size_t rows = 0, fixes = 0;
  double last_t = -1.0;
  for (std::string line; std::getline(cov, line); ++rows) {
    std::vector<double> f;
    std::stringstream fields(line);
    for (std::string x; std::getline(fields, x, ',');) f.push_back(std::stod(x));
    ASSERT_EQ(f.size(), 11u) << line;
    ASSERT_GE(f[0], last_t) << line;
    last_t = f[0];
    EXPECT_GT(f[4], 0.0) << line;
    EXPECT_GT(f[7], 0.0) << line;
    EXPECT_GT(f[9], 0.0) << line;
    fixes += f[10] == 1.0 ? 1 : 0;
  }
  EXPECT_EQ(rows, online.size() + position_only.size());
  EXPECT_EQ(fixes, position_only.size());
  const nlohmann::json& c = text["covariance_online"];
  EXPECT_EQ(c["poses"], rows) << c;
  EXPECT_EQ(c["not_positive_definite"], 0) << c;
  for (const char* share : {"horizontal_in_95", "vertical_in_95"}) {
    EXPECT_GT(c[share].get<double>(), 0.0) << c;
    EXPECT_LE(c[share].get<double>(), 1.0) << c;
  }
  EXPECT_GT(c["nees_mean"].get<double>(), 0.0) << c;
}


TEST(RiloReplay, MeasurementKindsAndReceptionAreCountedInTheSummary) {
  testing::TempDir out("rilo-replay-reception");
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", out.path().string(), "--measurements", "range", "--reception", "0.7",
                     "--reception-seed", "3", "--smoother", "ekf"}),
            0);
  nlohmann::json summary = testing::readJsonFile(out / "summary.json");
  nlohmann::json& m = summary["measurements"];
  EXPECT_EQ(m["selected"], "range") << summary;
  EXPECT_EQ(m["reception"], 0.7) << summary;
  EXPECT_EQ(m["reception_seed"], 3) << summary;
  EXPECT_EQ(m["tdoa"], nlohmann::json::parse(R"({"recorded": 0, "used": 0, "dropped": 0, "selected": false,
                                                 "flagged_one": 0, "flagged_both": 0, "deep_nlos": 0})"))
      << summary;
  const std::size_t recorded = m["range"]["recorded"], used = m["range"]["used"], dropped = m["range"]["dropped"];
  EXPECT_EQ(used + dropped, recorded);
  EXPECT_NEAR(static_cast<double>(used) / static_cast<double>(recorded), 0.7, 0.05);
  EXPECT_EQ(summary["ranges_used"], used);
  // A kind the tool does not know, a reception outside [0, 1]: refused.
  EXPECT_NE(runRilo({"replay", rec, "--out", out.path().string(), "--measurements", "range,lidar"}), 0);
  EXPECT_NE(runRilo({"replay", rec, "--out", out.path().string(), "--reception", "1.5"}), 0);
}

std::string summaryOf(const std::filesystem::path& out) {
  std::ifstream summary(out / "summary.json");
  std::stringstream buffer;
  buffer << summary.rdbuf();
  return buffer.str();
}

// The height model's flags (issue 36) are the configuration's keys: the same
// trajectory from --range-lever / --height-hold-sigma as from a configuration
// that sets estimator.height_band, another one than the shipped defaults';
// a negative hold is refused.
TEST(RiloReplay, HeightModelFlagsAreTheConfigurationsKeys) {
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  testing::TempDir dir("rilo-replay-height");
  const std::string config = (dir / "rilod.yaml").string();
  // The shipped file with the band's lever and hold turned off.
  std::string text = testing::readFile(testing::sourceDir() / "config" / "rilod.yaml");
  const std::string key = "    range_lever: true";
  ASSERT_NE(text.find(key), std::string::npos);
  text.replace(text.find(key), key.size(), "    range_lever: false");
  const std::string hold = "    hold_sigma_m: 0.5";
  ASSERT_NE(text.find(hold), std::string::npos);
  text.replace(text.find(hold), hold.size(), "    hold_sigma_m: 0");
  // Relative paths of the shipped file point into config/: make them absolute.
  const std::string demo = "../tests/data/office-demo";
  for (std::size_t at = text.find(demo); at != std::string::npos; at = text.find(demo)) text.replace(at, demo.size(), rec);
  testing::writeFile(config, text);
  const std::vector<std::string> common = {"--measurements", "range", "--range-hz", "4"};
  auto run = [&](const std::string& name, std::vector<std::string> extra) {
    const std::string out = (dir / name).string();
    std::vector<std::string> args = {"replay", rec, "--out", out};
    args.insert(args.end(), common.begin(), common.end());
    args.insert(args.end(), extra.begin(), extra.end());
    EXPECT_EQ(runRilo(args), 0) << name;
    return testing::readFile(std::filesystem::path(out) / "online.tum");
  };
  const std::string by_flags = run("flags", {"--range-lever", "false", "--height-hold-sigma", "0"});
  const std::string by_config = run("config", {"--config", config});
  const std::string shipped = run("shipped", {});
  EXPECT_FALSE(by_flags.empty());
  EXPECT_TRUE(by_flags == by_config) << "the flags are not the configuration's keys";
  EXPECT_FALSE(by_flags == shipped) << "the height model changed nothing on the demo";
  EXPECT_NE(runRilo({"replay", rec, "--out", (dir / "bad").string(), "--height-hold-sigma", "-1"}), 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
}

TEST(RiloReplay, ConfigRunsTheServicesEstimatorAndOptionsOverrideIt) {
  const std::string rec = (testing::sourceDir() / "tests" / "data" / "office-demo").string();
  testing::TempDir dir("rilo-replay-config");
  // A rilod configuration with a smoother, noise model and lag of its own.
  const std::string config = (dir / "rilod.yaml").string();
  testing::writeFile(config,
                     "sources:\n  mode: replay\n  replay:\n    path: " + rec + "\n"
                     "anchors:\n  file: " + rec + "/anchors.csv\n"
                     "estimator:\n  smoother: isam2\n  lag_s: 4.0\n  range:\n    noise_model: cauchy\n");
  const std::string from_config = (dir / "from-config").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", from_config, "--config", config}), 0);
  const std::string text = summaryOf(from_config);
  EXPECT_NE(text.find("\"config\": \"" + config + "\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"smoother\": \"isam2\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"noise\": \"cauchy\""), std::string::npos) << text;
  EXPECT_NE(text.find("\"initializations\": 1"), std::string::npos) << text;

  const std::string overridden = (dir / "overridden").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", overridden, "--config", config, "--smoother", "d-isam2"}), 0);
  const std::string text2 = summaryOf(overridden);
  EXPECT_NE(text2.find("\"smoother\": \"d-isam2\""), std::string::npos) << text2;
  EXPECT_NE(text2.find("\"noise\": \"cauchy\""), std::string::npos) << text2;

  // Without --config: the shipped configuration, built in, and the summary
  // says so. One estimator: the same trajectory as with the file itself.
  const std::string own = (dir / "own").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", own, "--measurements", "range", "--range-hz", "1"}), 0);
  EXPECT_NE(summaryOf(own).find("\"config\": \"config/rilod.yaml (built in)\""), std::string::npos) << summaryOf(own);
  const std::string shipped = (dir / "shipped").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", shipped, "--measurements", "range", "--range-hz", "1", "--config",
                     (testing::sourceDir() / "config" / "rilod.yaml").string()}),
            0);
  const std::string own_online = testing::readFile(std::filesystem::path(own) / "online.tum");
  EXPECT_FALSE(own_online.empty());
  EXPECT_TRUE(own_online == testing::readFile(std::filesystem::path(shipped) / "online.tum"))
      << "the built-in configuration is not config/rilod.yaml";
  EXPECT_NE(summaryOf(own).find("\"device_from\": \"recording\""), std::string::npos) << summaryOf(own);

  // The device of the configuration instead of the recording's: this test's
  // configuration has the library's lever arm (0), the demo states 0.1 m.
  const std::string config_device = (dir / "config-device").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", config_device, "--config", config, "--device-from", "config"}), 0);
  EXPECT_NE(summaryOf(config_device).find("\"device_from\": \"config\""), std::string::npos);
  EXPECT_FALSE(testing::readFile(std::filesystem::path(config_device) / "online.tum") ==
               testing::readFile(std::filesystem::path(from_config) / "online.tum"));
  EXPECT_NE(runRilo({"replay", rec, "--out", (dir / "bad-device").string(), "--device-from", "board"}), 0);

  // The library's own estimator, as the replay ran without --config before:
  // no configuration in the summary, its 5 s lag.
  const std::string library = (dir / "library").string();
  ASSERT_EQ(runRilo({"replay", rec, "--out", library, "--measurements", "range", "--range-hz", "1",
                     "--library-defaults"}),
            0);
  EXPECT_NE(summaryOf(library).find("\"config\": null"), std::string::npos) << summaryOf(library);
  EXPECT_NE(summaryOf(library).find("\"lag_s\": 5"), std::string::npos) << summaryOf(library);
  EXPECT_NE(runRilo({"replay", rec, "--out", (dir / "both").string(), "--library-defaults", "--config", config}), 0);

  // A malformed configuration is refused before any replay, naming the key.
  testing::writeFile(config, "sources:\n  mode: replay\n  replay:\n    path: " + rec + "\nestimator:\n  lag_s: soon\n");
  EXPECT_NE(runRilo({"replay", rec, "--out", (dir / "bad").string(), "--config", config}), 0);
  EXPECT_FALSE(std::filesystem::exists(dir / "bad"));
}

TEST(RiloReplay, MissingRecordingIsAClearError) {
  const std::string exe = (testing::binaryDir() / "rilo").string();
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::execl(exe.c_str(), exe.c_str(), "replay", "/nonexistent/rec", "--out", "/tmp/x", static_cast<char*>(nullptr));
    ::_exit(127);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_NE(WEXITSTATUS(status), 127);
}

}  // namespace
}  // namespace rilo
