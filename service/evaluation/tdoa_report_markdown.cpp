#include "evaluation/tdoa_report_markdown.h"

#include "estimation/assembly/range_imu_graph.h"  // tdoa_max_power_gap_db
#include "evaluation/replay_run.h"  // kTdoaVerticalSpeedSigmaMs
#include "evaluation/report_cells.h"
#include "evaluation/report_text.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <stdexcept>

namespace rilo {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Appends the parts to out. (Not "literal" + std::string&&: GCC 12 reports a
/// false -Wrestrict for it at -O3.)
template <class... Parts>
void add(std::string& out, const Parts&... parts) {
  (out.append(parts), ...);
}

template <class... Parts>
std::string cat(const Parts&... parts) {
  std::string out;
  add(out, parts...);
  return out;
}

std::string estimatorLabel(const std::string& e) {
  if (e == "sliding-window") return "Sliding window (IMU-Ultrasonic-UWB paper)";
  if (e == "ekf") return "EKF";
  return report_detail::smootherLabel(e);  // the smoothers' labels, as in the two-way report
}

std::string receptionLabel(double p) { return strf("%g %%", 100.0 * p); }

/// Pooled statistics over runs: RMSE and mean weighted by matched poses, max the largest.
struct Pooled {
  std::size_t poses = 0, runs = 0, failed = 0;
  double sum_sq = 0.0, sum = 0.0, max = 0.0;
  void add(const ErrorStats& e) {
    poses += e.count;
    sum_sq += e.rmse * e.rmse * static_cast<double>(e.count);
    sum += e.mean * static_cast<double>(e.count);
    max = std::max(max, e.max);
    ++runs;
  }
  double rmse() const { return poses ? std::sqrt(sum_sq / static_cast<double>(poses)) : kNaN; }
  double mean() const { return poses ? sum / static_cast<double>(poses) : kNaN; }
};

/// Over the recordings' runs of (estimator, reception); `smoothed` picks the trajectory.
Pooled pooled(const std::vector<ReportRecording>& recordings, const TdoaReportResults& res, const std::string& estimator,
              double reception, bool smoothed) {
  Pooled p;
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    const TdoaRun* r = res.find(i, estimator, reception);
    if (r == nullptr || !r->has_truth) continue;
    if (r->failed(res.options.fail_mean_m)) {
      ++p.failed;
      continue;
    }
    p.add(smoothed ? r->ape_smoothed.ape_3d : r->ape_online.ape_3d);
  }
  return p;
}

/// The RMSE (m) a Table I cell shows, NaN when failed or unknown.
double rmseOf(const TdoaRun* r, double fail_mean_m, bool smoothed) {
  if (r == nullptr || !r->has_truth || r->failed(fail_mean_m)) return kNaN;
  const ErrorStats& e = smoothed ? r->ape_smoothed.ape_3d : r->ape_online.ape_3d;
  return e.count ? e.rmse : kNaN;
}

std::string rmseCell(const TdoaRun* r, double fail_mean_m, bool smoothed) {
  if (r == nullptr) return "–";
  if (!r->threw && !r->has_truth) return "n/a";
  if (r->failed(fail_mean_m)) return "Fail";
  const double v = rmseOf(r, fail_mean_m, smoothed);
  std::string cell = std::isfinite(v) ? strf("%.1f", 100.0 * v) : "–";
  if (r->reinitializations > 0) cell += strf(" (%llu re-init)", static_cast<unsigned long long>(r->reinitializations));
  return cell;
}

std::string percentCell(double v) { return std::isfinite(v) ? strf("%+.0f %%", v) : "–"; }

std::string pooledRmseCell(const Pooled& p) {
  if (p.runs == 0) return p.failed ? "Fail" : "–";
  std::string cell = strf("%.1f", 100.0 * p.rmse());
  if (p.failed) cell += strf(" (%zu failed left out)", p.failed);
  return cell;
}

/// Table I (IMU-Ultrasonic-UWB paper style): one row per estimator, RMSE in cm per recording
/// and pooled, then the improvement row.
std::string tableOne(const std::vector<ReportRecording>& recordings, const TdoaReportResults& res, double reception,
                     bool smoothed) {
  const TdoaReportOptions& o = res.options;
  std::string md = "| Method |";
  for (const ReportRecording& r : recordings) add(md, " ", cellText(r.label), " |");
  md += " All |\n|---|";
  for (std::size_t i = 0; i <= recordings.size(); ++i) md += "---:|";
  md += "\n";
  for (const std::string& e : o.estimators) {
    add(md, "| ", estimatorLabel(e), " |");
    for (std::size_t i = 0; i < recordings.size(); ++i) add(md, " ", rmseCell(res.find(i, e, reception), o.fail_mean_m, smoothed), " |");
    add(md, " ", pooledRmseCell(pooled(recordings, res, e, reception, smoothed)), " |\n");
  }
  const bool both = std::find(o.estimators.begin(), o.estimators.end(), o.proposed) != o.estimators.end() &&
                    std::find(o.estimators.begin(), o.estimators.end(), o.baseline) != o.estimators.end();
  if (both && o.proposed != o.baseline) {
    add(md, "| Improvement of ", estimatorLabel(o.proposed), " over ", estimatorLabel(o.baseline), " |");
    for (std::size_t i = 0; i < recordings.size(); ++i) {
      add(md, " ",
          percentCell(improvementPercent(rmseOf(res.find(i, o.proposed, reception), o.fail_mean_m, smoothed),
                                         rmseOf(res.find(i, o.baseline, reception), o.fail_mean_m, smoothed))),
          " |");
    }
    const Pooled p = pooled(recordings, res, o.proposed, reception, smoothed);
    const Pooled b = pooled(recordings, res, o.baseline, reception, smoothed);
    // Pooled only over the same recordings: a failed baseline would flatter the proposal.
    const bool comparable = p.failed == 0 && b.failed == 0 && p.runs == b.runs;
    add(md, " ", comparable ? percentCell(improvementPercent(p.rmse(), b.rmse())) : std::string("–"), " |\n");
  }
  return md;
}

std::string triple(const Pooled& p) {
  if (p.runs == 0) return p.failed ? "Fail" : "–";
  return strf("%.3f / %.3f / %.3f", p.rmse(), p.mean(), p.max);
}

}  // namespace

std::string tdoaResultsCsv(const std::vector<ReportRecording>& recordings, const TdoaReportResults& results) {
  std::string out = cat(kTdoaResultsCsvHeader, "\n");
  const TdoaReportOptions& o = results.options;
  const std::string dc = !o.dynamic_covariance ? "auto" : *o.dynamic_covariance ? "1" : "0";
  for (const TdoaRun& r : results.runs) {
    const std::string label = r.spec.recording < recordings.size() ? recordings[r.spec.recording].label : "?";
    const char* status = r.threw ? "error" : !r.has_truth ? "no-truth" : r.failed(o.fail_mean_m) ? "fail" : "ok";
    add(out, csvField(label), ",", r.spec.estimator, ",", strf("%g", r.spec.reception), ",",
        csvField(toString(o.measurements)), ",", dc, ",", status, ",");
    const bool ran = !r.threw;
    const auto num = [](bool known, double v) { return known ? strf("%.4f", v) : std::string(); };
    const bool on = ran && r.has_truth && r.ape_online.ape_3d.count > 0;
    const bool sm = ran && r.has_truth && r.ape_smoothed.ape_3d.count > 0;
    const ErrorStats& a = r.ape_online.ape_3d;
    const ErrorStats& s = r.ape_smoothed.ape_3d;
    add(out, num(on, a.rmse), ",", num(on, a.mean), ",", num(on, a.median), ",", num(on, a.max), ",", num(sm, s.rmse),
        ",", num(sm, s.mean), ",", num(sm, s.max), ",");
    const bool timed = ran && r.updates > 0;
    add(out, num(timed, r.update_mean_ms), ",", num(timed, r.update_p99_ms), ",", num(timed, r.update_max_ms), ",");
    const auto count = [ran](std::uint64_t v) { return ran ? std::to_string(v) : std::string(); };
    const MeasurementCounts& m = r.measurements;
    add(out, count(r.updates), ",", count(r.initializations), ",", count(r.reinitializations), ",", count(m.range.used),
        ",", count(m.range.dropped), ",", count(m.tdoa.used), ",", count(m.tdoa.dropped), ",", count(m.ultrasonic.used),
        ",", num(ran, r.wall_s), ",", csvField(r.error), ",", csvField(r.last_failure), "\n");
  }
  return out;
}

std::string tdoaReportMarkdown(const std::vector<ReportRecording>& recordings, const TdoaReportResults& results,
                               const ReportHeader& header) {
  const TdoaReportOptions& o = results.options;
  std::size_t failed = 0, threw = 0;
  for (const TdoaRun& r : results.runs) {
    if (r.failed(o.fail_mean_m)) ++failed;
    if (r.threw) ++threw;
  }
  std::string md = "# rilo TDoA system report\n\n";
  md += "The second system (\"Indoor Fusion Positioning Based on IMU-Ultrasonic-UWB and Factor Graph "
        "Optimization\"): UWB TDoA and ultrasonic ranges with an IMU, its sliding-window smoother against the EKF "
        "baseline and rilo's D-iSAM2, made with `rilo report --system tdoa`.\n\n";
  const auto known = [](const std::string& s) { return s.empty() ? std::string("unknown") : s; };
  add(md, "- Date: ", known(header.date), "\n- Machine: ", known(header.machine), "\n- CPU: ", known(header.cpu_model),
      strf(", %u processors available (nproc)\n", header.cpus), "- Version: ", known(header.version), "\n");
  if (!header.command.empty()) add(md, "- Command: `", header.command, "`\n");
  md += strf("- Runs: %zu (%zu failed, of which %zu threw) in %.1f s wall time on %d worker threads\n\n",
             results.runs.size(), failed, threw, results.wall_s, o.jobs);

  md += "## Recordings\n\n| # | Recording | Duration (s) | TDoA rows/s | Ultrasonic ranges/s | Ranges/s | UWB anchors | "
        "Ground truth | Folder |\n|---:|---|---:|---:|---:|---:|---:|---|---|\n";
  for (std::size_t i = 0; i < recordings.size(); ++i) {
    const ReportRecording& r = recordings[i];
    const double d = r.durationS() > 0.0 ? r.durationS() : kNaN;
    add(md, strf("| %zu | ", i + 1), cellText(r.label),
        strf(" | %.1f | %.1f | %.1f | %.1f | %zu | ", r.durationS(), static_cast<double>(r.data.tdoa.size()) / d,
             static_cast<double>(r.data.ultrasonic.size()) / d, static_cast<double>(r.data.ranges.size()) / d,
             r.uwbAnchors()),
        r.data.groundtruth.empty() ? std::string("no") : strf("%zu poses", r.data.groundtruth.size()), " | ",
        cellText(r.path.empty() ? "(in memory)" : r.path), " |\n");
  }

  std::string receptions;
  for (double p : o.receptions) add(receptions, receptions.empty() ? "" : ", ", receptionLabel(p));
  std::string estimators;
  for (const std::string& e : o.estimators) add(estimators, estimators.empty() ? "" : ", ", estimatorLabel(e), " (`", e, "`)");
  md += "\n## Settings\n\n";
  add(md, "- Estimators: ", estimators, "\n- Measurements fed: ", toString(o.measurements), " (the IMU always)\n");
  add(md, "- Packet receptions: ", receptions,
        strf("; below 100 %% each TDoA epoch (the rows of one time) and each range is kept with that probability "
             "(seed %llu), ultrasonic ranges all kept\n",
             static_cast<unsigned long long>(o.reception_seed)));
  md += strf("- Window / lag %.1f s; dynamic covariance (per-link TDoA/ultrasonic sigmas) %s; vertical speed prior "
             "%.3f m/s per %.2f s of states on every estimator (replay's default with TDoA; %.2f m/s on two-way "
             "ranges alone); TDoA rows with a packet whose RX level exceeds its first-path power by more than %.0f dB "
             "gated (not used; rows without receive diagnostics are all used); %s; other parameters: the library "
             "defaults and each recording's meta.yaml\n",
             o.lag_s,
             !o.dynamic_covariance ? "on for every estimator when TDoA is used (default)"
             : *o.dynamic_covariance ? "on for every estimator"
                                     : "off",
             kTdoaVerticalSpeedSigmaMs, RangeImuGraphParams().vertical_speed_correlation_s, kTwoWayVerticalSpeedSigmaMs,
             RangeImuGraphParams().tdoa_max_power_gap_db,
             RangeImuGraphParams().tdoa_gap_excess.enabled
                 ? "the graph estimators learn each packet's NLOS excess per gap bin from the rows' residuals and "
                   "take it off the rows (the EKF does not)"
                 : "no estimator learns the packets' NLOS excess");
  md += strf("- \"Fail\": the run threw, never produced a pose matched to the ground truth, or its mean online error "
             "exceeds %.0f m (diverged); failed runs are left out of the pooled column\n",
             o.fail_mean_m);
  md += "- Errors: 3D position error against the ground truth pose nearest in time (within 50 ms), no alignment. "
        "*Online*: the newest state after every update (what the service publishes); *smoothed*: the final estimate "
        "of every state (a filter's is its online one).\n";
  md += "- Per-update time: one estimator update (the graph: one smoother update; the EKF: one group of "
        "measurement updates), measured on this machine";
  md += o.jobs > 1 ? " with other runs in parallel (less reliable).\n" : ".\n";

  const double full = *std::max_element(o.receptions.begin(), o.receptions.end());
  add(md, "\n## Table I: 3D RMSE (cm), online, ", receptionLabel(full), " reception\n\n");
  md += "The IMU-Ultrasonic-UWB paper's Table I (office): proposed 12.3 cm, EKF 27.6 cm, a 38 % improvement.\n\n";
  md += tableOne(recordings, results, full, false);
  add(md, "\n## Table I: 3D RMSE (cm), smoothed, ", receptionLabel(full), " reception\n\n");
  md += tableOne(recordings, results, full, true);

  md += "\n## Accuracy and runtime per estimator (all recordings pooled)\n\n";
  md += "The IMU-Ultrasonic-UWB paper: 21 ms per optimization iteration on a Jetson Nano.\n\n";
  md += "| Method | Reception | Online RMSE / mean / max (m) | Smoothed RMSE / mean / max (m) | Update mean / p99 (ms) | "
        "Updates | Tracked | Re-initializations | Failed runs |\n|---|---:|---|---|---|---:|---:|---:|---:|\n";
  for (double p : o.receptions) {
    for (const std::string& e : o.estimators) {
      const Pooled on = pooled(recordings, results, e, p, false);
      const Pooled sm = pooled(recordings, results, e, p, true);
      double time_sum = 0.0, p99 = 0.0, tracked_s = 0.0, data_s = 0.0;
      std::size_t updates = 0, fails = 0;
      std::uint64_t reinits = 0;
      for (std::size_t i = 0; i < recordings.size(); ++i) {
        const TdoaRun* r = results.find(i, e, p);
        if (r == nullptr) continue;
        if (r->failed(o.fail_mean_m)) ++fails;
        if (r->threw) continue;
        time_sum += r->update_mean_ms * static_cast<double>(r->updates);
        updates += r->updates;
        p99 = std::max(p99, r->update_p99_ms);
        reinits += r->reinitializations;
        tracked_s += r->tracked_share * r->data_s;
        data_s += r->data_s;
      }
      add(md, "| ", estimatorLabel(e), " | ", receptionLabel(p), " | ", triple(on), " | ", triple(sm), " | ",
          updates ? strf("%.2f / %.2f", time_sum / static_cast<double>(updates), p99) : std::string("–"),
          strf(" | %zu | ", updates), data_s > 0.0 ? strf("%.0f %%", 100.0 * tracked_s / data_s) : std::string("–"),
          strf(" | %llu | %zu |\n", static_cast<unsigned long long>(reinits), fails));
    }
  }
  md += strf("\nThe p99 column is the largest of the recordings' p99. Tracked: the share of the recordings' time the "
              "online estimate covered (a pose at most %g s old), failed runs included; the RMSE columns are over the "
              "poses there are.\n",
              static_cast<double>(kDefaultTrackedMaxAgeNs) * 1e-9);

  for (double p : o.receptions) {
    if (p == full) continue;
    add(md, "\n## ", receptionLabel(p), " packet reception: 3D RMSE (cm), online\n\n");
    md += "The IMU-Ultrasonic-UWB paper: robust \"down to a 40 % packet reception rate\". A run diverged when it failed or needed a "
          "re-initialization.\n\n";
    md += tableOne(recordings, results, p, false);
    md += "\n| Method | Diverged runs | Recordings |\n|---|---:|---|\n";
    for (const std::string& e : o.estimators) {
      std::size_t diverged = 0;
      std::string which;
      for (std::size_t i = 0; i < recordings.size(); ++i) {
        const TdoaRun* r = results.find(i, e, p);
        if (r == nullptr || !(r->failed(o.fail_mean_m) || r->reinitializations > 0)) continue;
        ++diverged;
        add(which, which.empty() ? "" : ", ", recordings[i].label);
      }
      add(md, "| ", estimatorLabel(e), strf(" | %zu of %zu | ", diverged, recordings.size()),
          cellText(which.empty() ? "–" : which), " |\n");
    }
  }

  md += "\n## Failed runs\n\n";
  if (failed == 0) {
    md += "None.\n";
  } else {
    md += "| Recording | Method | Reception | Reason |\n|---|---|---:|---|\n";
    for (const TdoaRun& r : results.runs) {
      if (!r.failed(o.fail_mean_m)) continue;
      std::string reason;
      if (r.threw) {
        add(reason, "threw: ", r.error);
      } else if (r.ape_online.ape_3d.count == 0) {
        add(reason, "no online pose matched the ground truth");
        if (!r.last_failure.empty()) add(reason, " (", r.last_failure, ")");
      } else {
        add(reason, strf("mean online error %.2f m", r.ape_online.ape_3d.mean));
        if (!r.last_failure.empty()) add(reason, "; last failure: ", r.last_failure);
      }
      add(md, "| ", cellText(recordings[r.spec.recording].label), " | ", estimatorLabel(r.spec.estimator), " | ",
          receptionLabel(r.spec.reception), " | ", cellText(reason), " |\n");
    }
  }
  add(md, "\n## Files\n\n- `", kReportCsvFile, "`: one row per run (", std::to_string(results.runs.size()), " rows): ",
      kTdoaResultsCsvHeader, "\n");
  return md;
}

void writeTdoaReport(const std::filesystem::path& dir, const std::vector<ReportRecording>& recordings,
                     const TdoaReportResults& results, const ReportHeader& header) {
  std::filesystem::create_directories(dir);
  const auto write = [](const std::filesystem::path& file, const std::string& text) {
    std::ofstream out(file, std::ios::binary);
    out << text;
    if (!out) throw std::runtime_error(cat("cannot write ", file.string()));
  };
  write(dir / kReportCsvFile, tdoaResultsCsv(recordings, results));
  write(dir / kReportMarkdownFile, tdoaReportMarkdown(recordings, results, header));
}

}  // namespace rilo
