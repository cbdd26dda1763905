#include "evaluation/golden_trace.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <numbers>
#include <stdexcept>
#include <system_error>

#include "math/so3.h"

namespace rilo {

namespace {

constexpr int kVersion = 1;
constexpr const char* kStateFields[6] = {"x_m", "y_m", "z_m", "yaw_deg", "pitch_deg", "roll_deg"};
constexpr int kStateDecimals[6] = {3, 3, 3, 2, 2, 2};
constexpr int kStateWidth[6] = {9, 9, 9, 8, 8, 8};
constexpr const char* kRecordKinds[] = {"golden_trace", "recording", "settings", "counts", "ape_online",
                                        "ape_smoothed"};

using TimedPose = RangeImuEstimator::TimedPose;

/// `value` with `decimals` decimals, right-aligned in `width`; "-0.000" becomes
/// "0.000" so sign flips of zero do not churn diffs.
std::string number(int decimals, double value, int width = 0) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%*.*f", width, decimals, value);
  std::string s(buf);
  const auto first = s.find_first_not_of(' ');
  if (first != std::string::npos && s[first] == '-' &&
      s.find_first_not_of("0.", first + 1) == std::string::npos) {
    s[first] = ' ';
    if (first == 0) s.erase(0, 1);
  }
  return s;
}

/// Shortest faithful-enough form of a setting or a difference ("%g").
std::string shortNumber(double value) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%g", value);
  return buf;
}

std::string optionalText(const std::optional<double>& v) { return v ? shortNumber(*v) : "default"; }
std::string optionalText(const std::optional<bool>& v) { return v ? (*v ? "true" : "false") : "default"; }

std::int64_t floorDiv(std::int64_t a, std::int64_t b) { return a / b - ((a % b != 0) && ((a < 0) != (b < 0))); }

/// Pose at `t_ns` interpolated between the last estimate at or before it and the
/// first one after it (the later of equal times wins: the newest re-estimate).
std::optional<Pose3> poseAt(const std::vector<TimedPose>& poses, std::int64_t t_ns, std::int64_t max_gap_ns) {
  const auto after = std::upper_bound(poses.begin(), poses.end(), t_ns,
                                      [](std::int64_t t, const TimedPose& p) { return t < p.t_ns; });
  if (after == poses.begin()) return std::nullopt;
  const TimedPose& a = *std::prev(after);
  if (a.t_ns == t_ns) return a.T_w_b;
  if (after == poses.end() || after->t_ns - a.t_ns > max_gap_ns) return std::nullopt;
  const TimedPose& b = *after;
  const double alpha = static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns);
  const Vec3 phi = so3::log(a.T_w_b.R.transpose() * b.T_w_b.R);
  return Pose3(a.T_w_b.R * so3::exp(alpha * phi), a.T_w_b.p + alpha * (b.T_w_b.p - a.T_w_b.p));
}

/// x y z (m), then ZYX Euler angles yaw pitch roll (deg) of R_w_b.
std::array<double, 6> stateNumbers(const Pose3& T) {
  constexpr double kDeg = 180.0 / std::numbers::pi;
  const Mat3& R = T.R;
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  return {T.p.x(), T.p.y(), T.p.z(), yaw * kDeg, pitch * kDeg, roll * kDeg};
}

std::string stateColumns(const std::optional<Pose3>& T) {
  if (!T) return " -";
  const std::array<double, 6> v = stateNumbers(*T);
  std::string out;
  for (int k = 0; k < 6; ++k) {
    out += ' ';
    out += number(kStateDecimals[k], v[static_cast<std::size_t>(k)], kStateWidth[k]);
  }
  return out;
}

std::string apeLine(const char* kind, const PositionErrorStats& s) {
  return std::string(kind) + " count=" + std::to_string(s.ape_3d.count) + " mean_m=" + number(4, s.ape_3d.mean) +
         " median_m=" + number(4, s.ape_3d.median) + " rmse_m=" + number(4, s.ape_3d.rmse) +
         " max_m=" + number(4, s.ape_3d.max) + " horizontal_mean_m=" + number(4, s.ape_horizontal.mean) +
         " vertical_mean_m=" + number(4, s.ape_vertical.mean) + "\n";
}

// ---- parsing ----

[[noreturn]] void parseError(const std::string& source, std::size_t line, const std::string& what) {
  throw std::runtime_error(source + ":" + std::to_string(line) + ": " + what);
}

std::vector<std::string_view> words(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

std::optional<double> parseDouble(std::string_view text) {
  double v = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<std::uint64_t> parseCount(std::string_view text) {
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return v;
}

enum class FieldKind { kText, kExactCount, kSizeCount, kApeMetres };

/// How a header field is compared (and validated when parsed).
FieldKind fieldKind(std::string_view kind, std::string_view key) {
  if (kind == "counts") {
    return key == "initializations" || key == "reinitializations" || key == "ranges_used" ? FieldKind::kExactCount
                                                                                          : FieldKind::kSizeCount;
  }
  if (kind == "ape_online" || kind == "ape_smoothed") {
    if (key == "count") return FieldKind::kSizeCount;
    if (key.ends_with("_m")) return FieldKind::kApeMetres;
  }
  return FieldKind::kText;
}

GoldenTrace::State parseState(const std::vector<std::string_view>& w, const std::string& source, std::size_t line) {
  GoldenTrace::State st;
  st.line = line;
  if (w.size() < 2) parseError(source, line, "state line without a time");
  const std::optional<double> t_s = parseDouble(w[1]);
  if (!t_s) parseError(source, line, "state time '" + std::string(w[1]) + "' is not a number");
  st.t_text = std::string(w[1]);
  st.t_ms = std::llround(*t_s * 1e3);
  std::size_t i = 2;
  for (const char* which : {"smoothed", "online"}) {
    if (i >= w.size() || w[i] != "|") {
      parseError(source, line, std::string("expected '|' before the ") + which + " pose (state line: t | 6 numbers or - | 6 numbers or -)");
    }
    ++i;
    std::optional<std::array<double, 6>>& pose = std::string_view(which) == "smoothed" ? st.smoothed : st.online;
    if (i < w.size() && w[i] == "-") {
      ++i;
      continue;
    }
    std::array<double, 6> v{};
    for (std::size_t k = 0; k < 6; ++k, ++i) {
      if (i >= w.size() || w[i] == "|") {
        parseError(source, line, std::string(which) + " pose has " + std::to_string(k) + " numbers, needs 6 or '-'");
      }
      const std::optional<double> x = parseDouble(w[i]);
      if (!x) {
        parseError(source, line, std::string(which) + "." + kStateFields[k] + " '" + std::string(w[i]) + "' is not a number");
      }
      v[k] = *x;
    }
    pose = v;
  }
  if (i != w.size()) parseError(source, line, "unexpected '" + std::string(w[i]) + "' after the online pose");
  return st;
}

// ---- comparison ----

std::string where(const std::string& source, std::size_t line) { return source + ":" + std::to_string(line); }

double wrapDegrees(double d) {
  d = std::fmod(d, 360.0);
  if (d > 180.0) d -= 360.0;
  if (d < -180.0) d += 360.0;
  return d;
}

void compareField(const std::string& at, std::string_view kind, const std::string& key, const std::string& expected,
                  const std::string& actual, const GoldenTolerances& tol, std::vector<std::string>& diffs) {
  const FieldKind fk = fieldKind(kind, key);
  const std::string label = at + " " + std::string(kind) + "." + key + ": expected " + expected + ", actual " + actual;
  if (fk == FieldKind::kText) {
    if (expected != actual) diffs.push_back(label);
    return;
  }
  const std::optional<double> e = parseDouble(expected), a = parseDouble(actual);
  if (!e || !a) {
    diffs.push_back(label + " (not a number)");
    return;
  }
  double allowed = 0.0;
  switch (fk) {
    case FieldKind::kExactCount: allowed = static_cast<double>(tol.count_slack); break;
    case FieldKind::kSizeCount: allowed = std::floor(tol.size_rel * std::abs(*e)); break;
    case FieldKind::kApeMetres: allowed = tol.ape_m; break;
    case FieldKind::kText: break;
  }
  const double off = std::abs(*a - *e);
  if (off > allowed + 1e-12) {
    diffs.push_back(label + " (off by " + shortNumber(off) + ", tolerance " + shortNumber(allowed) + ")");
  }
}

void compareRecords(const GoldenTrace& expected, const GoldenTrace& actual, const GoldenTolerances& tol,
                    std::vector<std::string>& diffs) {
  for (const GoldenTrace::Record& e : expected.records) {
    const std::string at = where(expected.source, e.line);
    const auto a = std::find_if(actual.records.begin(), actual.records.end(),
                                [&](const GoldenTrace::Record& r) { return r.kind == e.kind; });
    if (a == actual.records.end()) {
      diffs.push_back(at + " " + e.kind + ": line missing in " + actual.source);
      continue;
    }
    // Named references, not captured structured bindings (clang before 16: the fuzzing build).
    for (const auto& field : e.fields) {
      const std::string& key = field.first;
      const std::string& value = field.second;
      const auto af = std::find_if(a->fields.begin(), a->fields.end(), [&](const auto& f) { return f.first == key; });
      if (af == a->fields.end()) {
        diffs.push_back(at + " " + e.kind + "." + key + ": expected " + value + ", missing in " + actual.source);
      } else {
        compareField(at, e.kind, key, value, af->second, tol, diffs);
      }
    }
    for (const auto& field : a->fields) {
      const std::string& key = field.first;
      const std::string& value = field.second;
      if (std::none_of(e.fields.begin(), e.fields.end(), [&](const auto& f) { return f.first == key; })) {
        diffs.push_back(where(actual.source, a->line) + " " + e.kind + "." + key + ": actual " + value +
                        ", not in " + expected.source);
      }
    }
  }
  for (const GoldenTrace::Record& a : actual.records) {
    if (std::none_of(expected.records.begin(), expected.records.end(),
                     [&](const GoldenTrace::Record& r) { return r.kind == a.kind; })) {
      diffs.push_back(where(actual.source, a.line) + " " + a.kind + ": extra line, not in " + expected.source);
    }
  }
}

void comparePose(const std::string& at, const char* which, const std::optional<std::array<double, 6>>& e,
                 const std::optional<std::array<double, 6>>& a, const GoldenTolerances& tol,
                 std::vector<std::string>& diffs) {
  if (!e && !a) return;
  if (!e || !a) {
    diffs.push_back(at + " " + which + (e ? ": expected an estimate, actual '-' (none)" : ": expected '-' (none), actual has an estimate"));
    return;
  }
  for (std::size_t k = 0; k < 6; ++k) {
    const bool angle = k >= 3;
    const double off = angle ? std::abs(wrapDegrees((*a)[k] - (*e)[k])) : std::abs((*a)[k] - (*e)[k]);
    const double allowed = angle ? tol.angle_deg : tol.position_m;
    if (off > allowed) {
      const int f = angle ? 2 : 3;
      diffs.push_back(at + " " + which + "." + kStateFields[k] + ": expected " + number(f, (*e)[k]) + ", actual " +
                      number(f, (*a)[k]) + " (off by " + number(f, off) + ", tolerance " + number(f, allowed) + ")");
    }
  }
}

void compareStates(const GoldenTrace& expected, const GoldenTrace& actual, const GoldenTolerances& tol,
                   std::vector<std::string>& diffs) {
  // Both lists strictly increase in time (the parser checks): merge them.
  auto e = expected.states.begin();
  auto a = actual.states.begin();
  while (e != expected.states.end() || a != actual.states.end()) {
    if (a == actual.states.end() || (e != expected.states.end() && e->t_ms < a->t_ms)) {
      diffs.push_back(where(expected.source, e->line) + " t=" + e->t_text + " s: state line missing in " + actual.source);
      ++e;
    } else if (e == expected.states.end() || a->t_ms < e->t_ms) {
      diffs.push_back(where(actual.source, a->line) + " t=" + a->t_text + " s: extra state line, not in " + expected.source);
      ++a;
    } else {
      const std::string at = where(expected.source, e->line) + " t=" + e->t_text + " s";
      comparePose(at, "smoothed", e->smoothed, a->smoothed, tol, diffs);
      comparePose(at, "online", e->online, a->online, tol, diffs);
      ++e;
      ++a;
    }
  }
}

}  // namespace

std::string formatGoldenTrace(const Recording& rec, const ReplaySettings& settings, const ReplayResult& run,
                              const GoldenTraceOptions& options) {
  if (options.period_ns <= 0) throw std::invalid_argument("formatGoldenTrace: options.period_ns must be > 0");
  if (options.max_gap_ns < 0) throw std::invalid_argument("formatGoldenTrace: options.max_gap_ns must be >= 0");
  if (rec.imu.empty()) throw std::invalid_argument("formatGoldenTrace: rec has no IMU samples");
  std::string out;
  out += "# rilo golden trace of one replayRecording run (service/evaluation/golden_trace.h).\n";
  out += "golden_trace version=" + std::to_string(kVersion) + "\n";
  std::string name = rec.meta.name.empty() ? "-" : rec.meta.name;
  std::replace_if(name.begin(), name.end(), [](char c) { return c == ' ' || c == '\t' || c == '='; }, '_');
  out += "recording name=" + name + " imu=" + std::to_string(rec.imu.size()) + " ranges=" +
         std::to_string(rec.ranges.size()) + " groundtruth=" + std::to_string(rec.groundtruth.size()) + "\n";
  out += "settings smoother=" + settings.smoother + " noise=" + settings.noise + " range_hz=" +
         shortNumber(settings.range_hz) + " lag_s=" + shortNumber(settings.lag_s) +
         " range_sigma_m=" + optionalText(settings.range_sigma_m) + " nlos_scale_m=" + optionalText(settings.nlos_scale_m) +
         " nlos_weight=" + optionalText(settings.nlos_weight) + " height_band=" + optionalText(settings.height_band) +
         " floor_z_m=" + optionalText(settings.floor_z_m) + " min_height_m=" + optionalText(settings.min_height_m) +
         " max_height_m=" + optionalText(settings.max_height_m) +
         " vertical_speed_sigma_m_s=" + optionalText(settings.vertical_speed_sigma_m_s) +
         " zero_velocity_sigma_m_s=" + optionalText(settings.zero_velocity_sigma_m_s) + "\n";
  out += "counts initializations=" + std::to_string(run.initializations) +
         " reinitializations=" + std::to_string(run.reinitializations) +
         " ranges_used=" + std::to_string(run.ranges_used) + " updates=" + std::to_string(run.updates.size()) +
         " online=" + std::to_string(run.online.size()) + " smoothed=" + std::to_string(run.smoothed.size()) + "\n";
  if (!run.last_failure.empty()) out += "# last failure: " + run.last_failure + "\n";
  if (run.ape_online) out += apeLine("ape_online", *run.ape_online);
  if (run.ape_smoothed) out += apeLine("ape_smoothed", *run.ape_smoothed);

  // Online estimates come in processing order; sort a copy by time, keeping
  // that order among equal times so the newest re-estimate is found last.
  std::vector<TimedPose> online = run.online;
  std::stable_sort(online.begin(), online.end(), [](const TimedPose& a, const TimedPose& b) { return a.t_ns < b.t_ns; });
  std::vector<TimedPose> smoothed = run.smoothed;
  std::stable_sort(smoothed.begin(), smoothed.end(), [](const TimedPose& a, const TimedPose& b) { return a.t_ns < b.t_ns; });

  out += "# state t_s | smoothed x_m y_m z_m yaw_deg pitch_deg roll_deg | online (same); '-' = no estimate\n";
  const std::int64_t t_first = rec.imu.front().t_ns, t_last = rec.imu.back().t_ns;
  const std::int64_t k_first = floorDiv(t_first + options.period_ns - 1, options.period_ns);
  for (std::int64_t t = k_first * options.period_ns; t <= t_last; t += options.period_ns) {
    out += "state " + number(3, static_cast<double>(t) * 1e-9, 8) + " |" +
           stateColumns(poseAt(smoothed, t, options.max_gap_ns)) + " |" +
           stateColumns(poseAt(online, t, options.max_gap_ns)) + "\n";
  }
  return out;
}

std::string goldenTrace(const Recording& rec, const ReplaySettings& settings, const GoldenTraceOptions& options) {
  return formatGoldenTrace(rec, settings, replayRecording(rec, settings), options);
}

GoldenTrace parseGoldenTrace(std::string_view text, const std::string& source) {
  GoldenTrace trace;
  trace.source = source;
  std::size_t line_no = 0, pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const std::vector<std::string_view> w = words(line);
    if (w.empty() || w[0].front() == '#') continue;
    if (w[0] == "state") {
      GoldenTrace::State st = parseState(w, source, line_no);
      if (!trace.states.empty() && st.t_ms <= trace.states.back().t_ms) {
        parseError(source, line_no, "state time " + st.t_text + " s does not follow " + trace.states.back().t_text +
                                        " s (line " + std::to_string(trace.states.back().line) + ")");
      }
      trace.states.push_back(std::move(st));
      continue;
    }
    if (std::find(std::begin(kRecordKinds), std::end(kRecordKinds), w[0]) == std::end(kRecordKinds)) {
      parseError(source, line_no, "unknown line kind '" + std::string(w[0]) + "'");
    }
    for (const GoldenTrace::Record& r : trace.records) {
      if (r.kind == w[0]) parseError(source, line_no, "second '" + r.kind + "' line (first at line " + std::to_string(r.line) + ")");
    }
    GoldenTrace::Record rec;
    rec.line = line_no;
    rec.kind = std::string(w[0]);
    for (std::size_t i = 1; i < w.size(); ++i) {
      const std::size_t eq = w[i].find('=');
      if (eq == std::string_view::npos || eq == 0) {
        parseError(source, line_no, rec.kind + ": '" + std::string(w[i]) + "' is not key=value");
      }
      std::string key(w[i].substr(0, eq)), value(w[i].substr(eq + 1));
      for (const auto& f : rec.fields) {
        if (f.first == key) parseError(source, line_no, rec.kind + ": field '" + key + "' repeated");
      }
      switch (fieldKind(rec.kind, key)) {
        case FieldKind::kExactCount:
        case FieldKind::kSizeCount:
          if (!parseCount(value)) parseError(source, line_no, rec.kind + "." + key + " '" + value + "' is not a count");
          break;
        case FieldKind::kApeMetres:
          if (!parseDouble(value)) parseError(source, line_no, rec.kind + "." + key + " '" + value + "' is not a number");
          break;
        case FieldKind::kText: break;
      }
      rec.fields.emplace_back(std::move(key), std::move(value));
    }
    trace.records.push_back(std::move(rec));
  }
  return trace;
}

std::vector<std::string> compareTraces(const GoldenTrace& expected, const GoldenTrace& actual,
                                       const GoldenTolerances& tol) {
  std::vector<std::string> diffs;
  compareRecords(expected, actual, tol, diffs);
  compareStates(expected, actual, tol, diffs);
  return diffs;
}

std::vector<std::string> compareTraces(std::string_view expected_text, std::string_view actual_text,
                                       const GoldenTolerances& tol, const std::string& expected_source,
                                       const std::string& actual_source) {
  return compareTraces(parseGoldenTrace(expected_text, expected_source), parseGoldenTrace(actual_text, actual_source),
                       tol);
}

}  // namespace rilo
