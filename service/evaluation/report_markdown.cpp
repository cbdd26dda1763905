#include "evaluation/report_markdown.h"

#include <sched.h>
#include <sys/utsname.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>

#include "evaluation/report_cells.h"
#include "evaluation/report_text.h"
#include "evaluation/svg_plot.h"

namespace rilo {

using namespace report_detail;

namespace {

constexpr double kGapS = 1.0;             // trajectory gaps longer than this break the plotted line
constexpr std::size_t kMaxPlotPoints = 3000;
const double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---------------------------------------------------------------------------
// figures

struct Figure {
  std::string file;  ///< relative to the report folder
  std::string alt;
  svg::Plot plot;
};

/// Keeps every k-th point (k so that at most kMaxPlotPoints remain) and every
/// point next to a gap (NaN), so gaps survive.
void decimate(std::vector<double>& x, std::vector<double>& y) {
  if (x.size() <= kMaxPlotPoints) return;
  const std::size_t stride = (x.size() + kMaxPlotPoints - 1) / kMaxPlotPoints;
  std::vector<double> dx, dy;
  for (std::size_t i = 0; i < x.size(); ++i) {
    const bool gap_here = std::isnan(x[i]);
    const bool near_gap = (i > 0 && std::isnan(x[i - 1])) || (i + 1 < x.size() && std::isnan(x[i + 1]));
    if (gap_here || near_gap || i % stride == 0 || i + 1 == x.size()) {
      dx.push_back(x[i]);
      dy.push_back(y[i]);
    }
  }
  x.swap(dx);
  y.swap(dy);
}

const ReportRun* headlineRun(const ReportResults& results, std::size_t recording) {
  const ReportOptions& o = results.options;
  return results.find(recording, o.headlineSmoother(), o.headlineNoise(), o.full_rate_hz);
}

std::string headlineName(const ReportOptions& o) {
  return noiseLabel(o.headlineNoise()) + ", " + smootherLabel(o.headlineSmoother()) + ", " +
         rateLabel(o.full_rate_hz);
}

std::vector<Figure> reportFigures(const std::vector<ReportRecording>& recordings, const ReportResults& results) {
  const ReportOptions& o = results.options;
  std::vector<Figure> figures;

  // Fig. 7: mean APE over the recordings vs rate, one line per noise model.
  {
    Figure f;
    f.file = std::string(kReportFiguresDir) + "/fig7_ape_vs_rate.svg";
    f.alt = "Fig. 7: mean 3D APE vs ranging rate";
    svg::Plot& p = f.plot;
    p.title = "Mean 3D APE over the recordings vs ranging rate (" + smootherLabel(o.headlineSmoother()) + ", online)";
    p.x.label = "Ranging rate (total, Hz; log scale)";
    p.x.log = true;
    p.y.label = "Mean 3D APE (m)";
    p.y.min = 0.0;
    const std::vector<double> rates = figureRates(o);
    for (double r : rates) p.x.ticks.push_back({r, rateLabel(r)});
    p.x.min = rates.front() / 1.3;
    p.x.max = rates.back() * 1.3;
    for (const std::string& noise : o.noises) {
      svg::Series s;
      s.label = noiseLabel(noise);
      s.color = noiseColor(noise);
      s.marker = noiseMarker(noise);
      s.line_width_px = 2.0;
      for (double r : rates) {
        std::vector<Cell> cells;
        for (std::size_t i = 0; i < recordings.size(); ++i) {
          cells.push_back(apeCell(results.find(i, o.headlineSmoother(), noise, r), o.fail_mean_m, false));
        }
        const Cell avg = averageCell(cells);
        s.x.push_back(r);
        s.y.push_back(avg.kind == Cell::Kind::kValue ? avg.mean : kNaN);
      }
      p.series.push_back(std::move(s));
    }
    figures.push_back(std::move(f));
  }

  // Fig. 1 per recording: top view and error over time of the headline configuration.
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    const ReportRecording& rec = recordings[i];
    const ReportRun* run = headlineRun(results, i);
    const std::string base = std::string(kReportFiguresDir) + "/fig1_" + fileSafeLabel(rec.label);
    {
      Figure f;
      f.file = base + "_top.svg";
      f.alt = rec.label + ": top view";
      svg::Plot& p = f.plot;
      p.title = rec.label + ": top view (" + headlineName(o) + ")";
      if (run != nullptr && run->has_truth && !run->threw && run->ape_online.ape_3d.count > 0) {
        p.title += strf(", APE %.2f/%.2f m", run->ape_online.ape_3d.mean, run->ape_online.ape_3d.max);
      }
      p.x.label = "x (m)";
      p.y.label = "y (m)";
      p.equal_aspect = true;
      p.height_px = 560;
      p.width_px = 760;
      if (!rec.data.groundtruth.empty()) {
        svg::Series gt;
        gt.label = "Ground truth";
        gt.color = "#555555";
        gt.line_width_px = 1.5;
        for (const GroundTruthPose& g : rec.data.groundtruth) {
          gt.x.push_back(g.p_w_b.x());
          gt.y.push_back(g.p_w_b.y());
        }
        decimate(gt.x, gt.y);
        p.series.push_back(std::move(gt));
      }
      if (run != nullptr && !run->online.empty()) {
        svg::Series est;
        est.label = "Online estimate";
        est.color = "#1f77b4";
        est.line_width_px = 1.3;
        std::int64_t last_ns = run->online.front().t_ns;
        for (const auto& pose : run->online) {
          if (static_cast<double>(pose.t_ns - last_ns) * 1e-9 > kGapS) {
            est.x.push_back(kNaN);
            est.y.push_back(kNaN);
          }
          last_ns = pose.t_ns;
          est.x.push_back(pose.T_w_b.p.x());
          est.y.push_back(pose.T_w_b.p.y());
        }
        decimate(est.x, est.y);
        p.series.push_back(std::move(est));
      }
      svg::Series anchors;
      anchors.label = "UWB anchors";
      anchors.color = "#d62728";
      anchors.line_width_px = 0.0;
      anchors.marker = svg::Marker::kSquare;
      anchors.marker_size_px = 4.5;
      for (const Anchor& a : rec.data.anchors) {
        if (a.kind != AnchorKind::kUwb) continue;
        anchors.x.push_back(a.p_w_anchor.x());
        anchors.y.push_back(a.p_w_anchor.y());
      }
      if (!anchors.x.empty()) p.series.push_back(std::move(anchors));
      figures.push_back(std::move(f));
    }
    if (run != nullptr && !run->online.empty() && !rec.data.groundtruth.empty()) {
      const std::vector<ErrorSample> errors = errorOverTime(run->online, rec.data);
      if (errors.empty()) continue;
      Figure f;
      f.file = base + "_error.svg";
      f.alt = rec.label + ": error over time";
      svg::Plot& p = f.plot;
      p.title = rec.label + ": online position error (" + headlineName(o) + ")";
      p.x.label = "Time since the start (s)";
      p.y.label = "Error (m)";
      p.y.min = 0.0;
      p.height_px = 380;
      p.width_px = 760;
      svg::Series e3{"3D", {}, {}, "#222222", 1.4};
      svg::Series eh{"Horizontal", {}, {}, "#1f77b4", 1.2};
      svg::Series ev{"Vertical", {}, {}, "#ff7f0e", 1.2};
      double last_t = errors.front().t_s;
      for (const ErrorSample& e : errors) {
        if (e.t_s - last_t > kGapS) {
          for (svg::Series* s : {&e3, &eh, &ev}) {
            s->x.push_back(kNaN);
            s->y.push_back(kNaN);
          }
        }
        last_t = e.t_s;
        e3.x.push_back(e.t_s);
        e3.y.push_back(e.error_3d_m);
        eh.x.push_back(e.t_s);
        eh.y.push_back(e.error_horizontal_m);
        ev.x.push_back(e.t_s);
        ev.y.push_back(e.error_vertical_m);
      }
      for (svg::Series* s : {&e3, &eh, &ev}) {
        decimate(s->x, s->y);
        p.series.push_back(std::move(*s));
      }
      figures.push_back(std::move(f));
    }
  }
  return figures;
}

std::string failReason(const ReportRun& run, double fail_mean_m) {
  if (run.threw) return "threw: " + run.error;
  if (run.initializations == 0) return "never initialized (no estimate)";
  if (run.ape_online.ape_3d.count == 0) return "no online estimate matched the ground truth";
  return strf("mean APE %.2f m > %.2f m", run.ape_online.ape_3d.mean, fail_mean_m);
}

std::string statOr(const ReportRun* run, bool smoothed, int which) {
  if (run == nullptr) return "–";
  if (run->threw) return "Fail";
  if (!run->has_truth) return "n/a";
  const PositionErrorStats& s = smoothed ? run->ape_smoothed : run->ape_online;
  if (s.ape_3d.count == 0) return "Fail";
  const ErrorStats& e = which == 0 ? s.ape_3d : which == 1 ? s.ape_horizontal : s.ape_vertical;
  return strf("%.2f/%.2f", e.mean, e.max);
}

/// The signed height offset (trajectory_error.h) of a run's online or smoothed estimate, or why there is none.
std::string heightOffsetOr(const ReportRun* run, bool smoothed) {
  if (run == nullptr || run->threw || !run->has_truth) return "–";
  const PositionErrorStats& s = smoothed ? run->ape_smoothed : run->ape_online;
  return s.ape_3d.count == 0 ? "–" : strf("%+.2f", s.vertical_bias_m);
}

}  // namespace

std::string fileSafeLabel(const std::string& label) {
  std::string out;
  for (char c : label) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '-' || c == '_';
    out += ok ? c : '_';
  }
  if (out.empty() || out.front() == '.') out.insert(out.begin(), '_');
  return out;
}

ReportHeader currentReportHeader(const std::string& command, const std::string& version) {
  ReportHeader h;
  h.command = command;
  h.version = version;
  {
    const std::time_t now = std::time(nullptr);
    std::tm local{};
    char buf[64];
    if (localtime_r(&now, &local) != nullptr && std::strftime(buf, sizeof buf, "%Y-%m-%d %H:%M:%S %z", &local) > 0) {
      h.date = buf;
    }
  }
  utsname u{};
  if (uname(&u) == 0) {
    h.machine = std::string(u.sysname) + " " + u.release + " " + u.machine + " (" + u.nodename + ")";
  }
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) {
    h.cpus = static_cast<unsigned>(CPU_COUNT(&set));
  } else {
    h.cpus = std::thread::hardware_concurrency();
  }
  {
    std::ifstream cpuinfo("/proc/cpuinfo");
    std::string line;
    while (std::getline(cpuinfo, line)) {
      if (line.rfind("model name", 0) == 0) {
        const std::size_t colon = line.find(':');
        if (colon != std::string::npos) h.cpu_model = line.substr(line.find_first_not_of(' ', colon + 1));
        break;
      }
    }
  }
  return h;
}

std::string resultsCsv(const std::vector<ReportRecording>& recordings, const ReportResults& results) {
  std::string out = std::string(kResultsCsvHeader) + "\n";
  const double fail = results.options.fail_mean_m;
  for (const ReportRun& r : results.runs) {
    const std::string label = r.spec.recording < recordings.size() ? recordings[r.spec.recording].label : "?";
    const char* status = r.threw ? "error" : !r.has_truth ? "no-truth" : r.failed(fail) ? "fail" : "ok";
    out += csvField(label) + "," + r.spec.smoother + "," + r.spec.noise + "," + strf("%g", r.spec.rate_hz) + "," +
           (r.spec.all_ranges ? "1" : "0") + "," + status + ",";
    const bool ape = !r.threw && r.has_truth;
    const auto num = [](bool known, int decimals, double v) { return known ? strf("%.*f", decimals, v) : std::string(); };
    const bool online = ape && r.ape_online.ape_3d.count > 0;
    const bool smoothed = ape && r.ape_smoothed.ape_3d.count > 0;
    out += num(online, 4, r.ape_online.ape_3d.mean) + "," + num(online, 4, r.ape_online.ape_3d.max) + "," +
           num(smoothed, 4, r.ape_smoothed.ape_3d.mean) + "," + num(smoothed, 4, r.ape_smoothed.ape_3d.max) +
           "," + num(online, 4, r.ape_online.ape_horizontal.mean) + "," +
           num(online, 4, r.ape_online.ape_vertical.mean) + "," + num(online, 4, r.ape_online.vertical_bias_m) + ",";
    const bool ran = !r.threw;
    out += num(ran && r.updates > 0, 4, r.update_mean_ms) + "," + num(ran && r.updates > 0, 4, r.update_max_ms) +
           "," + (ran ? std::to_string(r.updates) : "") + "," + num(ran, 2, r.realtime_factor) + "," +
           (ran ? std::to_string(r.initializations) : "") + "," + (ran ? std::to_string(r.reinitializations) : "") +
           "," + (ran ? std::to_string(r.ranges_used) : "") + "," + num(ran, 3, r.wall_s) + "," +
           csvField(r.error) + "," + csvField(r.last_failure) + "\n";
  }
  return out;
}

std::string reportMarkdown(const std::vector<ReportRecording>& recordings, const ReportResults& results,
                           const ReportHeader& header) {
  const ReportOptions& o = results.options;
  const double fail = o.fail_mean_m;
  const std::string head_smoother = o.headlineSmoother();
  const std::string head_noise = o.headlineNoise();
  const std::vector<Figure> figures = reportFigures(recordings, results);
  const std::vector<std::string> columns = recordingColumns(recordings);
  std::size_t threw = 0, failed = 0;
  for (const ReportRun& r : results.runs) {
    if (r.threw) ++threw;
    if (r.failed(fail)) ++failed;
  }

  std::string md = "# rilo evaluation report\n\n";
  md += "Evaluation matrix of \"Robust Indoor Localization with Ranging-IMU Fusion\" (Sec. VI) run with "
        "`rilo report`.\n\n";
  md += "- Date: " + (header.date.empty() ? std::string("unknown") : header.date) + "\n";
  md += "- Machine: " + (header.machine.empty() ? std::string("unknown") : header.machine) + "\n";
  md += "- CPU: " + (header.cpu_model.empty() ? std::string("unknown") : header.cpu_model) +
        strf(", %u processors available (nproc)\n", header.cpus);
  md += "- Version: " + (header.version.empty() ? std::string("unknown") : header.version) +
        "\n";
  if (!header.command.empty()) md += "- Command: `" + header.command + "`\n";
  md += strf("- Runs: %zu (%zu failed, of which %zu threw) in %.1f s wall time on %d worker threads\n\n",
             results.runs.size(), failed, threw, results.wall_s, o.jobs);

  md += "## Recordings\n\n| # | Recording | Duration (s) | IMU samples | Ranges | Range rate (Hz) | UWB anchors | "
        "Ground truth | Folder |\n|---:|---|---:|---:|---:|---:|---:|---|---|\n";
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    const ReportRecording& r = recordings[i];
    md += strf("| %zu | ", i + 1) + cellText(r.label) +
          strf(" | %.1f | %zu | %zu | %.1f | %zu | ", r.durationS(), r.data.imu.size(), r.data.ranges.size(),
               r.rangeRateHz(), r.uwbAnchors()) +
          (r.data.groundtruth.empty() ? "no" : strf("%zu poses", r.data.groundtruth.size())) + " | " +
          cellText(r.path.empty() ? "(in memory)" : r.path) + " |\n";
  }

  std::vector<std::string> smoother_labels, noise_labels, rate_labels;
  for (const std::string& s : o.smoothers) smoother_labels.push_back(smootherLabel(s) + " (`" + s + "`)");
  for (const std::string& n : o.noises) noise_labels.push_back(noiseLabel(n) + " (`" + n + "`)");
  for (double r : figureRates(o)) rate_labels.push_back(rateLabel(r));
  md += "\n## Settings\n\n";
  md += "- Estimators: " + joinList(smoother_labels) + "\n";
  md += "- Range noise models: " + joinList(noise_labels) + "\n";
  md += "- Ranging rates (Fig. 7): " + joinList(rate_labels) + strf("; %g Hz and above replay every range of the "
                                                                     "recording, lower rates thin the ranges to that total rate\n",
                                                                     o.full_rate_hz);
  md += "- Headline configuration (Fig. 1, Table III noise, Tables II and Fig. 7 estimator): " + headlineName(o) + "\n";
  md += strf("- Fixed lag %.1f s; other parameters: the library defaults and each recording's meta.yaml (IMU noise, "
             "lever arm)\n",
             o.lag_s);
  md += strf("- \"Fail\": the run threw, no online estimate matched the ground truth, or the mean APE exceeds "
             "%.0f m (paper, Table II)\n",
             fail);
  md += "- APE: absolute position error against the ground truth pose nearest in time (within 50 ms), no "
        "alignment (the anchors fix the frame). *Online* is what the service publishes (the newest state after "
        "every update, causal); *smoothed* is the final fixed-lag estimate of every state.\n";
  md += "- Cells are mean/max in metres; bold: within 5 % of the best in its column (mean and max separately), "
        "as in the paper. *Mean* averages the recordings' means and maxima.\n\n";

  // Table I.
  for (const bool smoothed : {false, true}) {
    md += smoothed ? "## Table I (smoothed): 3D APE (m) of the smoothed trajectory, " + rateLabel(o.full_rate_hz) +
                         " (all ranges), mean/max\n\n"
                   : "## Table I: 3D APE (m) with each range noise model and estimator, " +
                         rateLabel(o.full_rate_hz) + " (all ranges), online, mean/max\n\n";
    std::vector<TableRow> rows;
    for (const std::string& s : o.smoothers) {
      for (const std::string& n : o.noises) {
        rows.push_back({{noiseLabel(n), smootherLabel(s)}, rowCells(recordings, results, s, n, o.full_rate_hz, smoothed)});
      }
    }
    md += renderCellTable({"Noise model", "Estimator"}, columns, rows, true) + "\n";
  }

  // Table II.
  md += "## Table II: 3D APE (m) with " + rateLabel(o.low_rate_hz) + " ranging, " + smootherLabel(head_smoother) +
        ", online, mean/max\n\n";
  {
    std::vector<TableRow> rows;
    for (const std::string& n : o.noises) {
      rows.push_back({{noiseLabel(n)}, rowCells(recordings, results, head_smoother, n, o.low_rate_hz, false)});
    }
    md += renderCellTable({"Noise model"}, columns, rows, true);
    md += strf("\nFail: mean APE above %.0f m, no estimate, or the run threw (see *Failed runs*).\n\n", fail);
  }

  // Fig. 7.
  md += "## Fig. 7: mean 3D APE over the recordings vs ranging rate (" + smootherLabel(head_smoother) + ", online)\n\n";
  md += "![Fig. 7: mean 3D APE vs ranging rate](" + std::string(kReportFiguresDir) + "/fig7_ape_vs_rate.svg)\n\n";
  {
    std::vector<std::string> rate_cols;
    for (double r : figureRates(o)) rate_cols.push_back(rateLabel(r));
    std::vector<TableRow> rows;
    for (const std::string& n : o.noises) {
      TableRow row{{noiseLabel(n)}, {}};
      for (double r : figureRates(o)) {
        std::vector<Cell> cells;
        for (std::size_t i = 0; i < recordings.size(); ++i) {
          cells.push_back(apeCell(results.find(i, head_smoother, n, r), fail, false));
        }
        row.cells.push_back(averageCell(cells));
      }
      rows.push_back(std::move(row));
    }
    md += "Data of the figure: mean over the recordings of the mean APE (m); a point is missing from the plot when "
          "a recording failed at that rate.\n\n";
    md += renderCellTable({"Noise model"}, rate_cols, rows, false) + "\n";
  }

  // Table III.
  md += "## Table III: per-update runtime of each estimator (" + noiseLabel(head_noise) + ", " +
        rateLabel(o.full_rate_hz) + ")\n\n";
  md += "| Estimator | Runs | Updates | Average runtime (ms) | Max runtime (ms) | Real-time factor |\n"
        "|---|---:|---:|---:|---:|---:|\n";
  for (const std::string& s : o.smoothers) {
    std::size_t runs = 0, updates = 0, threw_here = 0;
    double sum_ms = 0.0, max_ms = 0.0, data_s = 0.0, wall_s = 0.0;
    for (std::size_t i = 0; i < recordings.size(); ++i) {
      const ReportRun* r = results.find(i, s, head_noise, o.full_rate_hz);
      if (r == nullptr) continue;
      if (r->threw) {
        ++threw_here;
        continue;
      }
      ++runs;
      updates += r->updates;
      sum_ms += r->update_sum_ms;
      max_ms = std::max(max_ms, r->update_max_ms);
      data_s += r->data_s;
      wall_s += r->wall_s;
    }
    md += "| " + smootherLabel(s) + strf(" | %zu", runs) + (threw_here ? strf(" (+%zu threw)", threw_here) : "") +
          strf(" | %zu | ", updates) + (updates ? strf("%.2f | %.2f", sum_ms / static_cast<double>(updates), max_ms) : "– | –") +
          " | " + (wall_s > 0.0 ? strf("%.1f", data_s / wall_s) : "–") + " |\n";
  }
  md += strf("\nPooled over the recordings: average over every update, maximum of all updates; real-time factor = "
             "recording time / replay wall time (whole pipeline). Runs shared the machine (%d worker threads on %u "
             "processors, possibly other load), so the times are indicative.\n\n",
             o.jobs, header.cpus);

  // Headline configuration: horizontal vs vertical, re-initializations.
  md += "## Headline configuration (" + headlineName(o) + "): horizontal vs vertical APE (m, mean/max)\n\n";
  md += "| Recording | Online 3D | Online horizontal | Online vertical | Online height offset | Smoothed 3D | "
        "Smoothed horizontal | Smoothed vertical | Smoothed height offset | Initializations | Re-initializations | "
        "First estimate (s) | Last tracking failure |\n"
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|\n";
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    const ReportRun* r = headlineRun(results, i);
    md += "| " + cellText(recordings[i].label);
    for (const bool smoothed : {false, true}) {
      for (int which = 0; which < 3; ++which) md += " | " + statOr(r, smoothed, which);
      md += " | " + heightOffsetOr(r, smoothed);
    }
    if (r == nullptr || r->threw) {
      md += " | – | – | – | " + cellText(r ? "threw: " + r->error : std::string("not run")) + " |\n";
      continue;
    }
    const std::string first_fix =
        !r->online.empty() && !recordings[i].data.imu.empty()
            ? strf("%.1f", static_cast<double>(r->online.front().t_ns - recordings[i].data.imu.front().t_ns) * 1e-9)
            : std::string("never");
    md += strf(" | %llu | %llu | ", static_cast<unsigned long long>(r->initializations),
               static_cast<unsigned long long>(r->reinitializations)) +
          first_fix + " | " + cellText(r->last_failure.empty() ? "–" : r->last_failure) + " |\n";
  }

  md += "\n## Re-initializations of every run\n\nTimes tracking was lost and initialization restarted (\"E\": the run "
        "threw).\n\n| Estimator | Noise model | Rate |";
  for (const ReportRecording& r : recordings) appendCell(md, cellText(r.label));
  md += "\n|---|---|---:|";
  for (std::size_t i = 0; i < recordings.size(); ++i) md += "---:|";
  md += "\n";
  {
    std::vector<const ReportRunSpec*> configs;
    for (const ReportRun& r : results.runs) {
      if (r.spec.recording != 0) continue;
      configs.push_back(&r.spec);
    }
    for (const ReportRunSpec* c : configs) {
      md += "| " + smootherLabel(c->smoother) + " | " + noiseLabel(c->noise) + " | " + rateLabel(c->rate_hz) + " |";
      for (std::size_t i = 0; i < recordings.size(); ++i) {
        const ReportRun* r = results.find(i, c->smoother, c->noise, c->rate_hz);
        md += r == nullptr ? " – |"
              : r->threw   ? " E |"
                           : strf(" %llu |", static_cast<unsigned long long>(r->reinitializations));
      }
      md += "\n";
    }
  }

  // Fig. 1.
  md += "\n## Fig. 1: trajectories and error over time (" + headlineName(o) + ")\n\n";
  md += "Top view: ground truth (grey), online estimate (blue; gaps where tracking was lost), UWB anchors (red). "
        "Error: online position error against the ground truth, 3D, horizontal and vertical.\n\n";
  for (const Figure& f : figures) {
    if (f.file.find("/fig1_") == std::string::npos) continue;
    md += "![" + cellText(f.alt) + "](" + f.file + ")\n\n";
  }

  // Failed runs.
  md += "## Failed runs\n\n";
  if (failed == 0) {
    md += "None.\n";
  } else {
    md += "| Recording | Estimator | Noise model | Rate | Reason | Last tracking failure |\n|---|---|---|---:|---|---|\n";
    for (const ReportRun& r : results.runs) {
      if (!r.failed(fail)) continue;
      md += "| " + cellText(recordings[r.spec.recording].label) + " | " + smootherLabel(r.spec.smoother) + " | " +
            noiseLabel(r.spec.noise) + " | " + rateLabel(r.spec.rate_hz) + " | " + cellText(failReason(r, fail)) +
            " | " + cellText(r.last_failure.empty() ? "–" : r.last_failure) + " |\n";
    }
  }
  md += "\n## Files\n\n- `" + std::string(kReportCsvFile) + "`: one row per run (" +
        std::to_string(results.runs.size()) + " rows): " + kResultsCsvHeader + "\n- `" + kReportFiguresDir +
        "/`: the SVG figures\n";
  return md;
}

void writeReport(const std::filesystem::path& dir, const std::vector<ReportRecording>& recordings,
                 const ReportResults& results, const ReportHeader& header) {
  std::filesystem::create_directories(dir / kReportFiguresDir);
  for (const Figure& f : reportFigures(recordings, results)) svg::writeSvg(dir / f.file, f.plot);
  const auto write = [](const std::filesystem::path& file, const std::string& text) {
    std::ofstream out(file, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error("cannot write " + file.string());
  };
  write(dir / kReportCsvFile, resultsCsv(recordings, results));
  write(dir / kReportMarkdownFile, reportMarkdown(recordings, results, header));
}

}  // namespace rilo
