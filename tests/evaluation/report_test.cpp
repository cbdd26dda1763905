#include "evaluation/report.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "evaluation/report_markdown.h"

namespace rilo {
namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string trim(const std::string& s) {
  const std::size_t a = s.find_first_not_of(' ');
  if (a == std::string::npos) return "";
  return s.substr(a, s.find_last_not_of(' ') - a + 1);
}

std::string unbold(std::string s) {
  for (std::size_t p = s.find("**"); p != std::string::npos; p = s.find("**")) s.erase(p, 2);
  return s;
}

// --- results.csv ------------------------------------------------------------

std::vector<std::string> splitCsvLine(const std::string& line) {
  std::vector<std::string> fields;
  std::string field;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.push_back(field);
      field.clear();
    } else {
      field += c;
    }
  }
  fields.push_back(field);
  return fields;
}

using CsvRow = std::map<std::string, std::string>;

std::vector<CsvRow> parseCsv(const std::string& text) {
  std::istringstream in(text);
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = splitCsvLine(line);
  std::vector<CsvRow> rows;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = splitCsvLine(line);
    if (f.size() != header.size()) throw std::runtime_error("csv row with " + std::to_string(f.size()) + " fields");
    CsvRow row;
    for (std::size_t i = 0; i < f.size(); ++i) row[header[i]] = f[i];
    rows.push_back(row);
  }
  return rows;
}

// --- Markdown tables -----------------------------------------------------------

struct MdTable {
  std::vector<std::string> header;
  std::vector<std::vector<std::string>> rows;

  std::size_t column(const std::string& name) const {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) throw std::runtime_error("no column " + name);
    return static_cast<std::size_t>(it - header.begin());
  }
  /// The row whose first cells are `labels`.
  const std::vector<std::string>& row(const std::vector<std::string>& labels) const {
    for (const auto& r : rows) {
      if (std::equal(labels.begin(), labels.end(), r.begin())) return r;
    }
    throw std::runtime_error("no row " + labels.front());
  }
};

std::vector<std::string> splitRow(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  for (std::size_t i = 1; i < line.size(); ++i) {
    if (line[i] == '\\' && i + 1 < line.size() && line[i + 1] == '|') {
      cell += '|';
      ++i;
    } else if (line[i] == '|') {
      cells.push_back(trim(cell));
      cell.clear();
    } else {
      cell += line[i];
    }
  }
  return cells;
}

/// The first table after the line starting with `heading`.
MdTable tableAfter(const std::string& md, const std::string& heading) {
  const std::size_t at = md.find("\n" + heading);
  if (at == std::string::npos) throw std::runtime_error("no heading " + heading);
  std::istringstream in(md.substr(at + 1));
  std::string line;
  std::getline(in, line);  // the heading
  MdTable t;
  bool started = false;
  while (std::getline(in, line)) {
    if (line.rfind("|", 0) != 0) {
      if (started) break;
      continue;
    }
    if (!started) {
      t.header = splitRow(line);
      std::getline(in, line);  // |---|
      started = true;
      continue;
    }
    t.rows.push_back(splitRow(line));
  }
  return t;
}

std::pair<double, double> meanMax(const std::string& cell) {
  const std::string s = unbold(cell);
  const std::size_t slash = s.find('/');
  if (slash == std::string::npos) throw std::runtime_error("not mean/max: " + cell);
  return {std::stod(s.substr(0, slash)), std::stod(s.substr(slash + 1))};
}

std::string noiseLabel(const std::string& n) {
  if (n == "asymmetric") return "Asymmetric (proposed)";
  if (n == "gaussian") return "Gaussian";
  if (n == "huber") return "Huber";
  return "Cauchy";
}

std::string smootherLabel(const std::string& s) { return s == "d-isam2" ? "D-iSAM2" : s == "isam2" ? "iSAM2" : "RISE (dog-leg)"; }

/// The cell must show the CSV's mean/max (two decimals) or Fail.
void expectCellMatches(const std::string& cell, const CsvRow& row, const char* mean_col, const char* max_col) {
  SCOPED_TRACE(row.at("recording") + " " + row.at("smoother") + " " + row.at("noise") + " " + row.at("rate_hz"));
  if (row.at("status") != "ok") {
    EXPECT_EQ(cell, "Fail");
    return;
  }
  const auto [mean, max] = meanMax(cell);
  EXPECT_NEAR(mean, std::stod(row.at(mean_col)), 0.0051);
  EXPECT_NEAR(max, std::stod(row.at(max_col)), 0.0051);
}

ReportHeader testHeader() {
  ReportHeader h;
  h.date = "2026-01-01 00:00:00 +0000";
  h.machine = "test machine";
  h.cpus = 2;
  h.command = "rilo report (test)";
  return h;
}

// --- the matrix on a short simulated office walk ----------------------------------

TEST(ReportMatrix, QuickMatrixOnASimulatedWalkWritesConsistentReport) {
  const fs::path dir = fs::temp_directory_path() / ("rilo_report_test_" + std::to_string(::getpid()));
  fs::remove_all(dir);

  // A 20 s office walk made by the simulator library, and a copy without
  // ranges: every run on it throws and must show up as Fail.
  std::vector<ReportRecording> recordings;
  recordings.push_back(loadReportRecording(simulateReportRecording(1, 20.0, dir / "recordings" / "sim-1")));
  ASSERT_EQ(recordings[0].label, "sim-1");
  ASSERT_FALSE(recordings[0].data.groundtruth.empty());
  EXPECT_NEAR(recordings[0].durationS(), 20.0, 0.5);
  EXPECT_EQ(recordings[0].uwbAnchors(), 8u);
  ReportRecording broken = recordings[0];
  broken.label = "no-ranges";
  broken.path.clear();
  broken.data.ranges.clear();
  recordings.push_back(std::move(broken));

  ReportOptions options;
  options.makeQuick();
  options.jobs = 2;
  std::vector<std::pair<std::size_t, std::size_t>> progress;
  options.progress = [&progress](std::size_t done, std::size_t total) { progress.emplace_back(done, total); };
  const ReportResults results = runReport(recordings, options);

  // 8 runs at 40 Hz (4 noises x 2 smoothers) + 4 at 1 Hz (D-iSAM2), per recording.
  ASSERT_EQ(results.runs.size(), 24u);
  ASSERT_EQ(progress.size(), 25u);
  EXPECT_EQ(progress.front(), (std::pair<std::size_t, std::size_t>{0, 24}));
  for (std::size_t i = 1; i < progress.size(); ++i) EXPECT_EQ(progress[i].first, i);
  for (const ReportRun& r : results.runs) {
    if (r.spec.recording == 1) {
      EXPECT_TRUE(r.threw);
      EXPECT_NE(r.error.find("range"), std::string::npos) << r.error;
    } else {
      EXPECT_FALSE(r.threw) << r.error;
    }
    EXPECT_EQ(!r.online.empty(), r.spec.recording == 0 && r.spec.keep_trajectory);
  }
  const ReportRun* headline = results.find(0, "d-isam2", "asymmetric", 40.0);
  ASSERT_NE(headline, nullptr);
  EXPECT_TRUE(headline->spec.keep_trajectory);
  ASSERT_GT(headline->ape_online.ape_3d.count, 50u);
  EXPECT_FALSE(headline->failed(options.fail_mean_m));
  EXPECT_LT(headline->ape_online.ape_3d.mean, 3.0);
  EXPECT_GT(headline->updates, 100u);
  EXPECT_GT(headline->realtime_factor, 0.0);

  // The same runs on one thread give the same numbers (no shared state).
  {
    ReportOptions one;
    one.smoothers = {"d-isam2"};
    one.noises = {"asymmetric", "cauchy"};
    one.rates_hz = {40.0};
    one.low_rate_hz = 40.0;
    one.jobs = 1;
    const ReportResults serial = runReport({recordings[0]}, one);
    ASSERT_EQ(serial.runs.size(), 2u);
    for (const ReportRun& s : serial.runs) {
      const ReportRun* p = results.find(0, s.spec.smoother, s.spec.noise, 40.0);
      ASSERT_NE(p, nullptr);
      EXPECT_EQ(s.ape_online.ape_3d.count, p->ape_online.ape_3d.count);
      EXPECT_EQ(s.ape_online.ape_3d.mean, p->ape_online.ape_3d.mean);
      EXPECT_EQ(s.ape_smoothed.ape_3d.max, p->ape_smoothed.ape_3d.max);
      EXPECT_EQ(s.updates, p->updates);
    }
  }

  const fs::path out = dir / "report";
  writeReport(out, recordings, results, testHeader());
  const std::string md = readFile(out / kReportMarkdownFile);
  const std::vector<CsvRow> csv = parseCsv(readFile(out / kReportCsvFile));
  ASSERT_EQ(csv.size(), results.runs.size());

  for (const char* heading : {"# rilo evaluation report", "## Recordings", "## Settings", "## Table I:",
                              "## Table I (smoothed):", "## Table II:", "## Fig. 7:", "## Table III:",
                              "## Headline configuration", "## Re-initializations", "## Fig. 1:", "## Failed runs"}) {
    EXPECT_NE(md.find(heading), std::string::npos) << heading;
  }
  EXPECT_NE(md.find("test machine"), std::string::npos);

  // CSV: statuses and error messages.
  std::size_t errors = 0;
  for (const CsvRow& row : csv) {
    if (row.at("recording") == "no-ranges") {
      EXPECT_EQ(row.at("status"), "error");
      EXPECT_FALSE(row.at("error").empty());
      EXPECT_TRUE(row.at("ape_online_mean_m").empty());
      ++errors;
    } else {
      EXPECT_TRUE(row.at("error").empty());
      EXPECT_TRUE(row.at("status") == "ok" || row.at("status") == "fail") << row.at("status");
    }
  }
  EXPECT_EQ(errors, 12u);

  // Tables I (online, smoothed) and II show exactly the CSV's numbers or Fail.
  const MdTable t1 = tableAfter(md, "## Table I:");
  const MdTable t1s = tableAfter(md, "## Table I (smoothed):");
  const MdTable t2 = tableAfter(md, "## Table II:");
  ASSERT_EQ(t1.header, (std::vector<std::string>{"Noise model", "Estimator", "sim-1", "no-ranges", "Mean"}));
  ASSERT_EQ(t1.rows.size(), 8u);
  ASSERT_EQ(t2.rows.size(), 4u);
  std::size_t checked = 0;
  for (const CsvRow& row : csv) {
    const std::string noise = noiseLabel(row.at("noise")), smoother = smootherLabel(row.at("smoother"));
    if (row.at("all_ranges") == "1") {
      expectCellMatches(t1.row({noise, smoother})[t1.column(row.at("recording"))], row, "ape_online_mean_m",
                        "ape_online_max_m");
      expectCellMatches(t1s.row({noise, smoother})[t1s.column(row.at("recording"))], row, "ape_smoothed_mean_m",
                        "ape_smoothed_max_m");
      ++checked;
    } else {
      ASSERT_EQ(row.at("rate_hz"), "1");
      expectCellMatches(t2.row({noise})[t2.column(row.at("recording"))], row, "ape_online_mean_m", "ape_online_max_m");
      ++checked;
    }
  }
  EXPECT_EQ(checked, 24u);
  // A recording that failed everywhere makes the mean over recordings fail.
  // (On this 20 s walk the Gaussian and Huber models may not initialize at
  // all: the window's batch cost stays above the acceptance limit.)
  for (const auto& r : t1.rows) {
    const bool sim_failed = r[t1.column("sim-1")].rfind("Fail", 0) == 0;
    EXPECT_EQ(r[t1.column("Mean")], sim_failed ? "Fail (2 of 2)" : "Fail (1 of 2)") << r[0] << " " << r[1];
  }
  EXPECT_NE(t1.row({"Asymmetric (proposed)", "D-iSAM2"})[t1.column("sim-1")].rfind("Fail", 0), 0u);  // the headline runs
  // At least one bold (best) value per Table I column of the good recording.
  bool any_bold = false;
  for (const auto& r : t1.rows) any_bold = any_bold || r[t1.column("sim-1")].find("**") != std::string::npos;
  EXPECT_TRUE(any_bold);

  // Table III: the updates of the D-iSAM2 run, the recording without ranges counted as threw.
  const MdTable t3 = tableAfter(md, "## Table III:");
  const std::vector<std::string>& d_isam2 = t3.row({"D-iSAM2"});
  EXPECT_EQ(d_isam2[t3.column("Runs")], "1 (+1 threw)");
  EXPECT_EQ(d_isam2[t3.column("Updates")], std::to_string(headline->updates));
  EXPECT_NEAR(std::stod(d_isam2[t3.column("Average runtime (ms)")]), headline->update_mean_ms, 0.0051);
  EXPECT_NO_THROW(t3.row({"iSAM2"}));

  // Headline configuration: horizontal and vertical APE as in the CSV.
  const MdTable head = tableAfter(md, "## Headline configuration");
  const auto& sim_row = head.row({"sim-1"});
  const auto csv_head = std::find_if(csv.begin(), csv.end(), [](const CsvRow& r) {
    return r.at("recording") == "sim-1" && r.at("smoother") == "d-isam2" && r.at("noise") == "asymmetric" &&
           r.at("rate_hz") == "40";
  });
  ASSERT_NE(csv_head, csv.end());
  EXPECT_NEAR(meanMax(sim_row[head.column("Online horizontal")]).first,
              std::stod(csv_head->at("ape_online_horizontal_mean_m")), 0.0051);
  EXPECT_NEAR(meanMax(sim_row[head.column("Online vertical")]).first,
              std::stod(csv_head->at("ape_online_vertical_mean_m")), 0.0051);
  // The height offset is signed and no larger than the vertical mean error.
  const double offset = std::stod(csv_head->at("ape_online_vertical_bias_m"));
  EXPECT_NEAR(std::stod(sim_row[head.column("Online height offset")]), offset, 0.0051);
  EXPECT_LE(std::abs(offset), std::stod(csv_head->at("ape_online_vertical_mean_m")) + 1e-4);  // both rounded to 4 decimals
  EXPECT_EQ(head.row({"no-ranges"})[head.column("Online height offset")], "–");
  EXPECT_EQ(sim_row[head.column("Re-initializations")], csv_head->at("reinitializations"));
  EXPECT_EQ(head.row({"no-ranges"})[head.column("Online 3D")], "Fail");

  // Failed runs list every run of the recording without ranges with its message.
  const MdTable failed = tableAfter(md, "## Failed runs");
  std::size_t threw_rows = 0;
  for (const auto& r : failed.rows) {
    if (r[0] == "no-ranges") {
      EXPECT_EQ(r[failed.column("Reason")].rfind("threw: ", 0), 0u);
      ++threw_rows;
    }
  }
  EXPECT_EQ(threw_rows, 12u);

  // Figures: written, SVG, referenced by the report.
  for (const char* f : {"figures/fig7_ape_vs_rate.svg", "figures/fig1_sim-1_top.svg", "figures/fig1_sim-1_error.svg",
                        "figures/fig1_no-ranges_top.svg"}) {
    SCOPED_TRACE(f);
    const std::string svg = readFile(out / f);
    EXPECT_EQ(svg.rfind("<?xml", 0), 0u);
    EXPECT_NE(svg.find("</svg>"), std::string::npos);
    EXPECT_NE(md.find(std::string("(") + f + ")"), std::string::npos);
  }
  const std::string top = readFile(out / "figures/fig1_sim-1_top.svg");
  for (const char* label : {">Ground truth<", ">Online estimate<", ">UWB anchors<", ">x (m)<", ">y (m)<"}) {
    EXPECT_NE(top.find(label), std::string::npos) << label;
  }
  const std::string error_plot = readFile(out / "figures/fig1_sim-1_error.svg");
  for (const char* label : {">3D<", ">Horizontal<", ">Vertical<"}) {
    EXPECT_NE(error_plot.find(label), std::string::npos) << label;
  }
  EXPECT_FALSE(fs::exists(out / "figures/fig1_no-ranges_error.svg"));

  fs::remove_all(dir);
}

// --- the plan, options, and the writer on made-up results ---------------------------

TEST(ReportPlan, DefaultMatrixCoversTablesAndFigure) {
  ReportOptions o;
  const std::vector<ReportRunSpec> specs = planReportRuns(o, 2);
  // Table I: 3 smoothers x 4 noises at 40 Hz; Fig. 7: D-iSAM2 x 4 noises at 1, 2, 4, 8, 20 Hz.
  ASSERT_EQ(specs.size(), 2u * (12u + 20u));
  std::size_t keep = 0;
  for (const ReportRunSpec& s : specs) {
    EXPECT_EQ(s.all_ranges, s.rate_hz == 40.0);
    if (!s.all_ranges) {
      EXPECT_EQ(s.smoother, "d-isam2");
    }
    if (s.keep_trajectory) {
      ++keep;
      EXPECT_EQ(s.smoother, "d-isam2");
      EXPECT_EQ(s.noise, "asymmetric");
      EXPECT_TRUE(s.all_ranges);
    }
  }
  EXPECT_EQ(keep, 2u);
  for (std::size_t i = 0; i < specs.size(); ++i) {
    for (std::size_t j = i + 1; j < specs.size(); ++j) {
      EXPECT_FALSE(specs[i].recording == specs[j].recording && specs[i].smoother == specs[j].smoother &&
                   specs[i].noise == specs[j].noise && specs[i].rate_hz == specs[j].rate_hz);
    }
  }

  ReportOptions quick;
  quick.makeQuick();
  EXPECT_EQ(planReportRuns(quick, 1).size(), 12u);

  // Table II's 1 Hz and Table I's 40 Hz are run even if --rates lacks them.
  ReportOptions some;
  some.rates_hz = {4.0};
  some.smoothers = {"isam2"};
  some.noises = {"huber", "gaussian"};
  const auto few = planReportRuns(some, 1);
  EXPECT_EQ(few.size(), 6u);  // 40 Hz x 2, then 1, 4 and 40 Hz x 2 (40 Hz shared)
  EXPECT_EQ(some.headlineSmoother(), "isam2");
  EXPECT_EQ(some.headlineNoise(), "huber");
  std::size_t one_hz = 0;
  for (const auto& s : few) one_hz += s.rate_hz == 1.0 ? 1 : 0;
  EXPECT_EQ(one_hz, 2u);
}

TEST(ReportPlan, BadOptionsThrowNamingTheOption) {
  const auto expectThrowWith = [](ReportOptions o, const std::string& word) {
    try {
      o.validate();
      ADD_FAILURE() << "no exception for " << word;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(word), std::string::npos) << e.what();
    }
  };
  ReportOptions o;
  EXPECT_NO_THROW(o.validate());
  ReportOptions bad = o;
  bad.smoothers = {"gauss-newton"};
  expectThrowWith(bad, "smoothers");
  bad = o;
  bad.noises = {"tukey"};
  expectThrowWith(bad, "noises");
  bad = o;
  bad.noises.clear();
  expectThrowWith(bad, "noises");
  bad = o;
  bad.rates_hz = {1.0, 80.0};
  expectThrowWith(bad, "rates");
  bad = o;
  bad.rates_hz = {2.0, 2.0};
  expectThrowWith(bad, "rates");
  bad = o;
  bad.jobs = 0;
  expectThrowWith(bad, "jobs");
  bad = o;
  bad.smoothers = {"isam2", "isam2"};
  expectThrowWith(bad, "smoothers");
  EXPECT_THROW(runReport({}, o), std::invalid_argument);
}

TEST(ReportRunTest, FailedFollowsThePaperRule) {
  ReportRun r;
  r.has_truth = true;
  r.initializations = 1;
  r.ape_online.ape_3d.count = 10;
  r.ape_online.ape_3d.mean = 0.5;
  EXPECT_FALSE(r.failed(10.0));
  r.initializations = 0;  // position-only poses while initializing, never a full state
  EXPECT_TRUE(r.failed(10.0));
  r.initializations = 1;
  r.ape_online.ape_3d.mean = 10.5;
  EXPECT_TRUE(r.failed(10.0));
  r.ape_online.ape_3d.mean = 0.5;
  r.ape_online.ape_3d.count = 0;  // never produced an estimate
  EXPECT_TRUE(r.failed(10.0));
  r.has_truth = false;
  EXPECT_FALSE(r.failed(10.0));
  r.threw = true;
  EXPECT_TRUE(r.failed(10.0));
}

TEST(ReportParallel, EveryIndexRunsOnceAndErrorsPropagate) {
  for (int jobs : {1, 2, 4}) {
    std::vector<std::atomic<int>> hits(100);
    parallelFor(hits.size(), jobs, [&](std::size_t i) { hits[i].fetch_add(1); });
    for (const auto& h : hits) EXPECT_EQ(h.load(), 1);
  }
  EXPECT_THROW(parallelFor(10, 2,
                           [](std::size_t i) {
                             if (i == 3) throw std::runtime_error("boom");
                           }),
               std::runtime_error);
  EXPECT_NO_THROW(parallelFor(0, 2, [](std::size_t) { throw std::runtime_error("never"); }));
}

TEST(ReportParallel, ProgressCountsEachFinishedIndexOnceInOrder) {
  for (int jobs : {1, 3}) {
    std::vector<std::pair<std::size_t, std::size_t>> calls;  // no lock: parallelFor serializes progress
    parallelFor(
        20, jobs, [](std::size_t) {},
        [&](std::size_t done, std::size_t total) { calls.emplace_back(done, total); });
    ASSERT_EQ(calls.size(), 21u);
    for (std::size_t k = 0; k < calls.size(); ++k) {
      EXPECT_EQ(calls[k].first, k);
      EXPECT_EQ(calls[k].second, 20u);
    }
  }
  std::vector<std::size_t> none;
  parallelFor(0, 2, [](std::size_t) {}, [&](std::size_t done, std::size_t) { none.push_back(done); });
  EXPECT_EQ(none, std::vector<std::size_t>{0});
}

TEST(ReportErrorOverTime, PairsPosesWithTheNearestTruth) {
  Recording rec;
  rec.imu.push_back({});
  rec.imu.back().t_ns = 1'000'000'000;
  for (int k = 0; k < 10; ++k) {
    GroundTruthPose g;
    g.t_ns = 1'000'000'000 + k * 100'000'000LL;
    g.p_w_b = Vec3(static_cast<double>(k), 0.0, 1.0);
    rec.groundtruth.push_back(g);
  }
  std::vector<RangeImuEstimator::TimedPose> poses(3);
  poses[0].t_ns = 1'210'000'000;  // nearest truth k = 2 (10 ms away)
  poses[0].T_w_b.p = Vec3(2.0 + 3.0, 4.0, 1.0 + 0.5);
  poses[1].t_ns = 5'000'000'000;  // far from any truth: skipped
  poses[2].t_ns = 1'900'000'000;
  poses[2].T_w_b.p = Vec3(9.0, 0.0, 1.0);
  const std::vector<ErrorSample> e = errorOverTime(poses, rec);
  ASSERT_EQ(e.size(), 2u);
  EXPECT_NEAR(e[0].t_s, 0.21, 1e-12);
  EXPECT_NEAR(e[0].error_horizontal_m, 5.0, 1e-12);
  EXPECT_NEAR(e[0].error_vertical_m, 0.5, 1e-12);
  EXPECT_NEAR(e[0].error_3d_m, std::sqrt(25.25), 1e-12);
  EXPECT_NEAR(e[1].error_3d_m, 0.0, 1e-12);
}

/// Results made up by hand: the writer's highlighting and Fail rules.
TEST(ReportMarkdownTest, HighlightsTheBestWithinFivePercentAndMarksFailures) {
  std::vector<ReportRecording> recordings(1);
  recordings[0].label = "walk|1";  // a '|' must not break the table
  recordings[0].data.groundtruth.push_back({});
  ReportResults results;
  results.options.smoothers = {"d-isam2"};
  results.options.rates_hz = {1.0, 40.0};
  for (const ReportRunSpec& spec : planReportRuns(results.options, 1)) {
    ReportRun r;
    r.spec = spec;
    r.has_truth = true;
    r.ape_online.ape_3d.count = 100;
    r.ape_smoothed.ape_3d.count = 100;
    r.updates = 10;
    r.initializations = 1;
    r.update_sum_ms = 20.0;
    r.update_max_ms = 5.0;
    r.data_s = 60.0;
    r.wall_s = 3.0;
    const auto set = [&r](double mean, double max) {
      r.ape_online.ape_3d.mean = r.ape_smoothed.ape_3d.mean = mean;
      r.ape_online.ape_3d.max = r.ape_smoothed.ape_3d.max = max;
    };
    if (spec.rate_hz == 40.0) {
      if (spec.noise == "gaussian") set(1.00, 2.00);
      if (spec.noise == "huber") set(1.04, 3.00);  // within 5 % of the best mean
      if (spec.noise == "cauchy") set(1.10, 1.90);  // best max; 2.00 is more than 5 % above it
      if (spec.noise == "asymmetric") {
        r.threw = true;
        r.error = "singular, \"really\"";
      }
    } else {
      set(spec.noise == "gaussian" ? 12.0 : 0.5, 20.0);
    }
    results.runs.push_back(r);
  }
  const std::string md = reportMarkdown(recordings, results, testHeader());
  const MdTable t1 = tableAfter(md, "## Table I:");
  ASSERT_EQ(t1.header.size(), 3u);  // one recording: no Mean column
  EXPECT_EQ(t1.header[2], "walk|1");
  EXPECT_EQ(t1.row({"Gaussian", "D-iSAM2"})[2], "**1.00**/2.00");
  EXPECT_EQ(t1.row({"Huber", "D-iSAM2"})[2], "**1.04**/3.00");
  EXPECT_EQ(t1.row({"Cauchy", "D-iSAM2"})[2], "1.10/**1.90**");
  EXPECT_EQ(t1.row({"Asymmetric (proposed)", "D-iSAM2"})[2], "Fail");
  const MdTable t2 = tableAfter(md, "## Table II:");
  EXPECT_EQ(t2.row({"Gaussian"})[1], "Fail");  // mean 12 m > 10 m
  EXPECT_EQ(t2.row({"Huber"})[1], "**0.50**/**20.00**");
  const MdTable failed = tableAfter(md, "## Failed runs");
  ASSERT_EQ(failed.rows.size(), 2u);
  EXPECT_NE(md.find("threw: singular, \"really\""), std::string::npos);
  EXPECT_NE(md.find("mean APE 12.00 m > 10.00 m"), std::string::npos);
  const MdTable t3 = tableAfter(md, "## Table III:");
  EXPECT_EQ(t3.row({"D-iSAM2"})[t3.column("Runs")], "0 (+1 threw)");

  const std::vector<CsvRow> csv = parseCsv(resultsCsv(recordings, results));
  ASSERT_EQ(csv.size(), results.runs.size());
  const auto threw = std::find_if(csv.begin(), csv.end(), [](const CsvRow& r) { return r.at("status") == "error"; });
  ASSERT_NE(threw, csv.end());
  EXPECT_EQ(threw->at("error"), "singular, \"really\"");
  EXPECT_EQ(threw->at("recording"), "walk|1");
  const auto fail = std::find_if(csv.begin(), csv.end(), [](const CsvRow& r) { return r.at("status") == "fail"; });
  ASSERT_NE(fail, csv.end());
  EXPECT_EQ(fail->at("ape_online_mean_m"), "12.0000");
}

TEST(ReportMarkdownTest, FileSafeLabels) {
  EXPECT_EQ(fileSafeLabel("sim-seed-1"), "sim-seed-1");
  EXPECT_EQ(fileSafeLabel("my walk/2"), "my_walk_2");
  EXPECT_EQ(fileSafeLabel(".."), "_..");
  EXPECT_EQ(fileSafeLabel(""), "_");
  std::vector<ReportRecording> recs(3);
  recs[0].label = recs[1].label = recs[2].label = "walk";
  makeLabelsUnique(recs);
  EXPECT_EQ(recs[0].label, "walk");
  EXPECT_EQ(recs[1].label, "walk-2");
  EXPECT_EQ(recs[2].label, "walk-3");
}

}  // namespace
}  // namespace rilo
