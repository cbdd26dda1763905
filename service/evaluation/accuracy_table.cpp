#include "evaluation/accuracy_table.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "evaluation/report_text.h"

namespace rilo {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const std::vector<std::string> kCsvHeader = {
    "set",           "recording",    "started",        "online_mean_m",      "online_max_m",
    "smoothed_mean_m", "height_offset_m", "first_position_s", "first_full_state_s", "tracked_share",
    "update_mean_ms", "update_max_ms", "covariance_horizontal_in_95", "covariance_vertical_in_95", "error"};
/// Before session 44: the same without the covariance columns.
std::vector<std::string> headerWithoutCovariance() {
  std::vector<std::string> h = kCsvHeader;
  std::erase_if(h, [](const std::string& c) { return c.starts_with("covariance_"); });
  return h;
}

std::string rateLabel(double rate_hz, const AccuracyOptions& o) {
  return rate_hz >= o.full_rate_hz ? std::string("all ranges") : strf("%g Hz", rate_hz);
}

AccuracyRow rowOf(const ReplayResult& run) {
  AccuracyRow row;
  row.started = !run.online.empty() || !run.position_only.empty();
  if (run.ape_online && run.ape_online->ape_3d.count > 0) {
    row.online_mean_m = run.ape_online->ape_3d.mean;
    row.online_max_m = run.ape_online->ape_3d.max;
    row.height_offset_m = run.ape_online->vertical_bias_m;
  }
  if (run.ape_smoothed && run.ape_smoothed->ape_3d.count > 0) row.smoothed_mean_m = run.ape_smoothed->ape_3d.mean;
  row.first_position_s = run.first_position_s;
  row.first_full_state_s = run.first_full_state_s;
  row.tracked_share = run.online_tracked_share;
  if (run.covariance_online && run.covariance_online->poses > 0) {
    row.covariance_horizontal_in_95 = run.covariance_online->horizontal_in_95;
    row.covariance_vertical_in_95 = run.covariance_online->vertical_in_95;
  }
  if (run.updates.empty()) return row;
  double sum = 0.0, max = 0.0;
  for (const ReplayUpdate& u : run.updates) {
    sum += u.stats.time_s * 1e3;
    max = std::max(max, u.stats.time_s * 1e3);
  }
  row.update_mean_ms = sum / static_cast<double>(run.updates.size());
  row.update_max_ms = max;
  return row;
}

// --- CSV ---------------------------------------------------------------------

/// 10 significant digits: a run compared with its own CSV prints no change.
std::string csvNumber(double v) { return std::isfinite(v) ? strf("%.10g", v) : std::string(); }

std::string csvNumber(const std::optional<double>& v) { return v ? csvNumber(*v) : std::string(); }

/// Splits one CSV line (quoted fields with "" for a quote). nullopt: an unterminated quote.
std::optional<std::vector<std::string>> splitCsv(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  if (quoted) return std::nullopt;
  return fields;
}

// --- Markdown ------------------------------------------------------------------

std::string fixed(double v, int decimals) { return std::isfinite(v) ? strf("%.*f", decimals, v) : std::string("-"); }

std::string signedFixed(double v) { return std::isfinite(v) ? strf("%+.2f", v) : std::string("-"); }

/// "67 / 100 %" (shares in [0, 1]); "-" without the figures.
std::string shares(double horizontal, double vertical) {
  if (!std::isfinite(horizontal) || !std::isfinite(vertical)) return "-";
  return fixed(100.0 * horizontal, 0) + " / " + fixed(100.0 * vertical, 0) + " %";
}

std::string seconds(const std::optional<double>& v) { return v ? fixed(*v, 1) + " s" : std::string("-"); }

/// "before -> after" when a before figure exists and differs in print, else the figure.
std::string change(const std::string& before, const std::string& after) {
  if (before.empty() || before == after) return after;
  return before + " -> " + after;
}

struct SetSummary {
  std::size_t recordings = 0, started = 0, with_online = 0, with_smoothed = 0, with_covariance = 0;
  double online_sum = 0.0, smoothed_sum = 0.0, offset_sum = 0.0, covariance_h_sum = 0.0, covariance_v_sum = 0.0;
  double covarianceHorizontal() const { return with_covariance ? covariance_h_sum / static_cast<double>(with_covariance) : kNaN; }
  double covarianceVertical() const { return with_covariance ? covariance_v_sum / static_cast<double>(with_covariance) : kNaN; }
  double onlineMean() const { return with_online ? online_sum / static_cast<double>(with_online) : kNaN; }
  double smoothedMean() const { return with_smoothed ? smoothed_sum / static_cast<double>(with_smoothed) : kNaN; }
  double offsetMean() const { return with_online ? offset_sum / static_cast<double>(with_online) : kNaN; }
};

/// Per set, in the order the sets first appear.
std::vector<std::pair<std::string, SetSummary>> summarize(const std::vector<AccuracyRow>& rows) {
  std::vector<std::pair<std::string, SetSummary>> sets;
  for (const AccuracyRow& r : rows) {
    auto it = std::find_if(sets.begin(), sets.end(), [&](const auto& s) { return s.first == r.set; });
    if (it == sets.end()) it = sets.insert(sets.end(), {r.set, SetSummary{}});
    SetSummary& s = it->second;
    ++s.recordings;
    if (r.started) ++s.started;
    if (std::isfinite(r.online_mean_m)) {
      ++s.with_online;
      s.online_sum += r.online_mean_m;
      s.offset_sum += std::isfinite(r.height_offset_m) ? r.height_offset_m : 0.0;
    }
    if (std::isfinite(r.smoothed_mean_m)) {
      ++s.with_smoothed;
      s.smoothed_sum += r.smoothed_mean_m;
    }
    if (std::isfinite(r.covariance_horizontal_in_95) && std::isfinite(r.covariance_vertical_in_95)) {
      ++s.with_covariance;
      s.covariance_h_sum += r.covariance_horizontal_in_95;
      s.covariance_v_sum += r.covariance_vertical_in_95;
    }
  }
  return sets;
}

}  // namespace

Recording withoutFirstPath(const Recording& rec) {
  Recording out = rec;
  for (RangeSample& r : out.ranges) r.fp_power_dbm = kNaN;
  return out;
}

bool hasFirstPath(const Recording& rec) {
  return std::any_of(rec.ranges.begin(), rec.ranges.end(), [](const RangeSample& r) { return std::isfinite(r.fp_power_dbm); });
}

void AccuracyOptions::validate() const {
  if (rates_hz.empty()) throw std::invalid_argument("accuracy: --rates is empty");
  for (double r : rates_hz) {
    if (!(std::isfinite(r) && r > 0.0)) throw std::invalid_argument("accuracy: --rates must be finite and > 0 (Hz)");
  }
  if (!(full_rate_hz > 0.0)) throw std::invalid_argument("accuracy: full_rate_hz must be > 0");
  // One run per set and recording: a rate given twice, or two that both replay every range, would repeat a set.
  const auto full = std::count_if(rates_hz.begin(), rates_hz.end(), [this](double r) { return r >= full_rate_hz; });
  std::vector<double> sorted = rates_hz;
  std::sort(sorted.begin(), sorted.end());
  if (full > 1 || std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
    throw std::invalid_argument("accuracy: --rates repeats a rate (every rate from " + strf("%g", full_rate_hz) +
                                " Hz on replays all ranges)");
  }
  if (jobs < 1) throw std::invalid_argument("accuracy: --jobs must be >= 1");
}

std::vector<AccuracyRow> runAccuracyTable(const std::vector<AccuracyRecording>& recordings,
                                          const ReplaySettings& settings, const AccuracyOptions& options) {
  options.validate();
  if (recordings.empty()) throw std::invalid_argument("accuracy: no recordings");
  // The variants, recording-major within a group; the first-path-free copies made once, shared read-only.
  std::vector<std::optional<Recording>> stripped(recordings.size());
  struct Run {
    std::size_t recording;
    double rate_hz;
    bool strip;
    std::string set;
  };
  std::vector<std::string> groups;
  for (const AccuracyRecording& r : recordings) {
    if (std::find(groups.begin(), groups.end(), r.group) == groups.end()) groups.push_back(r.group);
  }
  std::vector<Run> runs;
  for (const std::string& group : groups) {
    for (double rate : options.rates_hz) {
      for (bool strip : {false, true}) {
        for (std::size_t i = 0; i < recordings.size(); ++i) {
          const AccuracyRecording& r = recordings[i];
          if (r.group != group) continue;
          if (strip && !(options.without_first_path && hasFirstPath(r.recording.data))) continue;
          if (strip && !stripped[i]) stripped[i] = withoutFirstPath(r.recording.data);
          runs.push_back({i, rate, strip, group + ", " + rateLabel(rate, options) + (strip ? ", first path removed" : "")});
        }
      }
    }
  }
  std::vector<AccuracyRow> rows(runs.size());
  // Each run writes its own row; the recordings and their copies are only read.
  parallelFor(runs.size(), options.jobs, [&](std::size_t k) {
    const Run& run = runs[k];
    ReplaySettings s = settings;
    s.progress = nullptr;
    s.range_hz = run.rate_hz >= options.full_rate_hz ? 0.0 : run.rate_hz;
    AccuracyRow row;  // a run that throws keeps no figure, only its error
    try {
      row = rowOf(replayRecording(run.strip ? *stripped[run.recording] : recordings[run.recording].recording.data, s));
    } catch (const std::exception& e) {
      row.error = e.what();
    } catch (...) {
      row.error = "unknown exception";
    }
    row.set = run.set;
    row.recording = recordings[run.recording].recording.label;
    rows[k] = std::move(row);
  }, options.progress);
  return rows;
}

void writeAccuracyCsv(const std::filesystem::path& file, const std::vector<AccuracyRow>& rows) {
  std::ofstream out(file);
  for (std::size_t i = 0; i < kCsvHeader.size(); ++i) out << (i ? "," : "") << kCsvHeader[i];
  out << '\n';
  for (const AccuracyRow& r : rows) {
    out << csvField(r.set) << ',' << csvField(r.recording) << ',' << (r.started ? 1 : 0) << ','
        << csvNumber(r.online_mean_m) << ',' << csvNumber(r.online_max_m) << ',' << csvNumber(r.smoothed_mean_m) << ','
        << csvNumber(r.height_offset_m) << ',' << csvNumber(r.first_position_s) << ','
        << csvNumber(r.first_full_state_s) << ',' << csvNumber(r.tracked_share) << ',' << csvNumber(r.update_mean_ms)
        << ',' << csvNumber(r.update_max_ms) << ',' << csvNumber(r.covariance_horizontal_in_95) << ','
        << csvNumber(r.covariance_vertical_in_95) << ',' << csvField(r.error) << '\n';
  }
  out.flush();
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

std::vector<AccuracyRow> readAccuracyCsv(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("cannot open " + file.string());
  const auto fail = [&](std::size_t line, const std::string& what) {
    return std::runtime_error(file.string() + ":" + std::to_string(line) + ": " + what);
  };
  std::string line;
  const auto getLine = [&in](std::string& text) {
    if (!std::getline(in, text)) return false;
    if (!text.empty() && text.back() == '\r') text.pop_back();  // a file saved with CRLF
    return true;
  };
  std::optional<std::vector<std::string>> header;
  if (getLine(line)) header = splitCsv(line);
  if (!header || (*header != kCsvHeader && *header != headerWithoutCovariance())) {
    throw fail(1, "not an accuracy.csv (expected the header " + kCsvHeader.front() + ",...," + kCsvHeader.back() + ")");
  }
  const bool with_covariance = *header == kCsvHeader;
  const std::vector<std::string>& columns = *header;
  std::vector<AccuracyRow> rows;
  for (std::size_t n = 2; getLine(line); ++n) {
    if (line.empty()) continue;
    const std::optional<std::vector<std::string>> f = splitCsv(line);
    if (!f) throw fail(n, "unterminated quote");
    if (f->size() != columns.size()) {
      throw fail(n, std::to_string(f->size()) + " fields, expected " + std::to_string(columns.size()));
    }
    const auto number = [&](std::size_t i) -> std::optional<double> {
      const std::string& s = (*f)[i];
      if (s.empty()) return std::nullopt;
      std::size_t used = 0;
      double v = kNaN;
      try {
        v = std::stod(s, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != s.size() || !std::isfinite(v)) throw fail(n, "field " + columns[i] + ": not a number: '" + s + "'");
      return v;
    };
    AccuracyRow r;
    r.set = (*f)[0];
    r.recording = (*f)[1];
    if ((*f)[2] != "0" && (*f)[2] != "1") throw fail(n, "field started: expected 0 or 1, got '" + (*f)[2] + "'");
    r.started = (*f)[2] == "1";
    r.online_mean_m = number(3).value_or(kNaN);
    r.online_max_m = number(4).value_or(kNaN);
    r.smoothed_mean_m = number(5).value_or(kNaN);
    r.height_offset_m = number(6).value_or(kNaN);
    r.first_position_s = number(7);
    r.first_full_state_s = number(8);
    r.tracked_share = number(9).value_or(0.0);
    r.update_mean_ms = number(10).value_or(kNaN);
    r.update_max_ms = number(11).value_or(kNaN);
    if (with_covariance) {
      r.covariance_horizontal_in_95 = number(12).value_or(kNaN);
      r.covariance_vertical_in_95 = number(13).value_or(kNaN);
    }
    r.error = f->back();
    rows.push_back(std::move(r));
  }
  return rows;
}

std::string accuracyMarkdown(const std::vector<AccuracyRow>& rows, const std::vector<AccuracyRow>* before,
                             const std::string& header) {
  std::map<std::pair<std::string, std::string>, const AccuracyRow*> old_rows;
  if (before) {
    for (const AccuracyRow& r : *before) old_rows[{r.set, r.recording}] = &r;
  }
  // A set is compared over the recordings both runs hold, and each mean
  // over those with the figure in both runs: a recording that stopped
  // starting must not improve its set's mean.
  std::vector<AccuracyRow> matched_after, matched_before;
  for (const AccuracyRow& r : rows) {
    const auto it = old_rows.find({r.set, r.recording});
    if (it == old_rows.end()) continue;
    AccuracyRow a = r, b = *it->second;
    if (!std::isfinite(a.online_mean_m) || !std::isfinite(b.online_mean_m)) {
      a.online_mean_m = b.online_mean_m = a.height_offset_m = b.height_offset_m = kNaN;
    }
    if (!std::isfinite(a.smoothed_mean_m) || !std::isfinite(b.smoothed_mean_m)) a.smoothed_mean_m = b.smoothed_mean_m = kNaN;
    if (!std::isfinite(a.covariance_horizontal_in_95) || !std::isfinite(b.covariance_horizontal_in_95) ||
        !std::isfinite(a.covariance_vertical_in_95) || !std::isfinite(b.covariance_vertical_in_95)) {
      a.covariance_horizontal_in_95 = b.covariance_horizontal_in_95 = kNaN;
      a.covariance_vertical_in_95 = b.covariance_vertical_in_95 = kNaN;
    }
    matched_after.push_back(std::move(a));
    matched_before.push_back(std::move(b));
  }
  std::map<std::string, SetSummary> old_sets, new_sets;
  for (const auto& [name, s] : summarize(matched_before)) old_sets[name] = s;
  for (const auto& [name, s] : summarize(matched_after)) new_sets[name] = s;

  std::ostringstream md;
  md << header << "\n\n";
  md << "Per set: mean over the recordings with an error figure (online: every published pose, position-only "
        "fixes included; smoothed: the final estimate of every state)";
  if (before) {
    md << "; \"before -> after\" where the figures differ, over the recordings both runs hold (compared) and, "
          "for each mean, those with the figure in both (a figure the earlier run lacks: this run's, over all)";
  }
  md << ".\n\n";
  md << "| set | recordings | " << (before ? "compared | " : "")
     << "started | online mean (m) | smoothed mean (m) | height offset (m) | in the covariance's 95 % (h / v) |\n";
  md << "|---|---|" << (before ? "---|" : "") << "---|---|---|---|---|\n";
  const std::vector<std::pair<std::string, SetSummary>> sets = summarize(rows);
  for (const auto& [name, all] : sets) {
    // Compared: both sides over the matched recordings; else this run's set alone.
    const auto o = old_sets.find(name);
    const SetSummary* b = o == old_sets.end() ? nullptr : &o->second;
    const SetSummary& a = b ? new_sets.at(name) : all;
    md << "| " << cellText(name) << " | " << all.recordings << " | ";
    if (before) md << (b ? a.recordings : 0) << " | ";
    md << change(b ? std::to_string(b->started) : "", std::to_string(a.started)) << " | "
       << change(b ? fixed(b->onlineMean(), 4) : "", fixed(a.onlineMean(), 4)) << " | "
       << change(b ? fixed(b->smoothedMean(), 4) : "", fixed(a.smoothedMean(), 4)) << " | "
       << change(b ? signedFixed(b->offsetMean()) : "", signedFixed(a.offsetMean())) << " | "
       << (b && b->with_covariance > 0
               ? change(shares(b->covarianceHorizontal(), b->covarianceVertical()),
                        shares(a.covarianceHorizontal(), a.covarianceVertical()))
               : shares(all.covarianceHorizontal(), all.covarianceVertical()))  // an earlier run without the figure
       << " |\n";
  }
  std::string only_before;
  if (before) {
    std::set<std::string> named;  // this run's sets, then those already listed
    for (const auto& [name, s] : sets) named.insert(name);
    for (const AccuracyRow& r : *before) {
      if (named.insert(r.set).second) only_before += (only_before.empty() ? "" : ", ") + cellText(r.set);
    }
  }
  if (!only_before.empty()) md << "\nOnly in the earlier run: " << only_before << ".\n";
  md << "\nPer run:\n\n";
  md << "| set | recording | online mean (m) | smoothed mean (m) | online max (m) | height offset (m) | "
        "first position / full state | tracked | in the covariance's 95 % (h / v) |\n";
  md << "|---|---|---|---|---|---|---|---|---|\n";
  for (const AccuracyRow& r : rows) {
    const auto it = old_rows.find({r.set, r.recording});
    const AccuracyRow* o = it == old_rows.end() ? nullptr : it->second;
    md << "| " << cellText(r.set) << " | " << cellText(r.recording) << " | ";
    if (!r.error.empty()) {
      md << "failed: " << cellText(r.error) << " | | | | | | |\n";
      continue;
    }
    if (!r.started) {
      md << change(o && o->started ? fixed(o->online_mean_m, 3) : "", "never started") << " | | | | | 0 % | |\n";
      continue;
    }
    const auto starts = [](const AccuracyRow& x) { return seconds(x.first_position_s) + " / " + seconds(x.first_full_state_s); };
    md << change(o ? (o->started ? fixed(o->online_mean_m, 3) : "never started") : "", fixed(r.online_mean_m, 3))
       << " | " << change(o ? fixed(o->smoothed_mean_m, 3) : "", fixed(r.smoothed_mean_m, 3)) << " | "
       << change(o ? fixed(o->online_max_m, 2) : "", fixed(r.online_max_m, 2)) << " | "
       << change(o ? signedFixed(o->height_offset_m) : "", signedFixed(r.height_offset_m)) << " | "
       << change(o ? starts(*o) : "", starts(r)) << " | "
       << change(o ? fixed(100.0 * o->tracked_share, 0) + " %" : "", fixed(100.0 * r.tracked_share, 0) + " %")
       << " | "
       << change(o && std::isfinite(o->covariance_horizontal_in_95)
                     ? shares(o->covariance_horizontal_in_95, o->covariance_vertical_in_95)
                     : "",
                 shares(r.covariance_horizontal_in_95, r.covariance_vertical_in_95))
       << " |\n";
  }
  return md.str();
}

}  // namespace rilo
