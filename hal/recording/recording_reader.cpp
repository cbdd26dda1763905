#include "hal/recording/recording_reader.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <unordered_map>
#include <utility>

#include "hal/recording/csv_parser.h"
#include "hal/recording/meta_yaml.h"
#include "hal/recording/number_text.h"
#include "hal/recording/recording_files.h"

namespace rilo {
namespace recording {
namespace {

constexpr int kAbsent = CsvReader::kAbsent;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool sameDouble(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

/// Opens `text` as a CSV; for a file without a header line, a required file
/// is an error and an optional one a warning (treated as absent).
CsvReader openCsv(std::string_view text, const std::string& file, std::span<const std::string_view> required,
                  std::span<const std::string_view> optional, bool file_required, ReadReport& report) {
  CsvReader csv(text, file, required, optional, report);
  if (!csv.hasHeader()) {
    if (file_required) throw RecordingError(file, 0, "", "empty file: no header line");
    report.warn(file, 0, "", "empty file (no header line): treated as absent");
  }
  return csv;
}

/// Runs `fn` for every data row. A failure on an unterminated last line is
/// a crash-truncated line: warning, row skipped. An unterminated last line
/// that passes is kept with a warning.
template <typename RowFn>
void forEachRow(CsvReader& csv, RowFn&& fn) {
  while (true) {
    try {
      if (!csv.next()) return;
      fn();
    } catch (const RecordingError& e) {
      if (!csv.rowUnterminated()) throw;
      csv.report().warn(csv.file(), csv.line(), e.column(),
                        "truncated last line (no newline) skipped: " + e.detail());
      ++csv.report().skipped_rows;
      return;
    }
    if (csv.rowUnterminated()) {
      csv.warn(kAbsent, "last line has no newline; kept, but it may have been cut short");
    }
  }
}

int parseLos(const CsvReader& csv, int col) {
  const std::string_view f = csv.field(col);
  if (f.empty()) return -1;
  if (f == "0") return 0;
  if (f == "1") return 1;
  csv.fail(col, quoteField(f) + " is not a valid los (0, 1 or empty)");
}

/// Time order of a strictly increasing file (imu, groundtruth). Returns false
/// if the row repeats the previous one exactly (warned, to be skipped).
template <typename Sample, typename Same>
bool admitStrict(CsvReader& csv, int t_col, const std::vector<Sample>& out, std::size_t prev_line,
                 const Sample& s, Same&& same) {
  if (out.empty()) return true;
  const Sample& prev = out.back();
  if (s.t_ns > prev.t_ns) return true;
  if (s.t_ns < prev.t_ns) {
    csv.fail(t_col, "t_ns " + std::to_string(s.t_ns) + " is before t_ns " + std::to_string(prev.t_ns) + " of line " +
                        std::to_string(prev_line) + " (rows must be sorted by time)");
  }
  if (!same(prev, s)) {
    csv.fail(t_col, "t_ns " + std::to_string(s.t_ns) + " repeats line " + std::to_string(prev_line) +
                        " with different values");
  }
  csv.warn(t_col, "duplicate of line " + std::to_string(prev_line) + " skipped");
  ++csv.report().skipped_rows;
  return false;
}

/// Time order of an event file (range, tdoa, ultrasonic): non-decreasing
/// t_ns; rows sharing a t_ns must differ in their key.
template <typename Sample>
class EventOrder {
 public:
  template <typename SameKey, typename Same>
  bool admit(CsvReader& csv, int t_col, const std::vector<Sample>& out, const Sample& s, SameKey&& same_key,
             Same&& same) {
    if (!out.empty() && s.t_ns < out.back().t_ns) {
      csv.fail(t_col, "t_ns " + std::to_string(s.t_ns) + " is before t_ns " + std::to_string(out.back().t_ns) +
                          " of line " + std::to_string(group_lines_.back()) + " (rows must be sorted by time)");
    }
    if (out.empty() || s.t_ns != out.back().t_ns) {
      group_start_ = out.size();
      group_lines_.clear();
    }
    for (std::size_t k = group_start_; k < out.size(); ++k) {
      if (!same_key(out[k], s)) continue;
      const std::size_t line = group_lines_[k - group_start_];
      if (!same(out[k], s)) {
        csv.fail(t_col, "t_ns " + std::to_string(s.t_ns) + " repeats line " + std::to_string(line) +
                            " (same t_ns and ids) with different values");
      }
      csv.warn(t_col, "duplicate of line " + std::to_string(line) + " skipped");
      ++csv.report().skipped_rows;
      return false;
    }
    return true;
  }
  /// Call after pushing an admitted row.
  void pushed(std::size_t line) { group_lines_.push_back(line); }

 private:
  std::size_t group_start_ = 0;
  std::vector<std::size_t> group_lines_;
};

class AnchorLookup {
 public:
  explicit AnchorLookup(const std::vector<Anchor>& anchors) {
    for (const Anchor& a : anchors) kinds_.emplace(a.id, a.kind);
  }
  /// Fails the row unless anchor `id` exists with kind `kind`.
  void check(const CsvReader& csv, int col, std::uint32_t id, AnchorKind kind) const {
    const auto it = kinds_.find(id);
    if (it == kinds_.end()) csv.fail(col, "anchor " + std::to_string(id) + " is not in anchors.csv");
    if (it->second != kind) {
      csv.fail(col, "anchor " + std::to_string(id) + " is of kind '" + std::string(toString(it->second)) +
                        "', expected '" + std::string(toString(kind)) + "'");
    }
  }

 private:
  std::unordered_map<std::uint32_t, AnchorKind> kinds_;
};

Vec3 requiredVec3(const CsvReader& csv, int cx, int cy, int cz) {
  return Vec3(csv.requiredDouble(cx), csv.requiredDouble(cy), csv.requiredDouble(cz));
}

}  // namespace

std::vector<Anchor> parseAnchors(std::string_view text, const std::string& file, ReadReport& report) {
  CsvReader csv = openCsv(text, file, kAnchorsRequired, kAnchorsOptional, true, report);
  const int c_id = csv.column("id"), c_x = csv.column("x"), c_y = csv.column("y"), c_z = csv.column("z");
  const int c_kind = csv.column("kind"), c_sigma = csv.column("sigma");
  std::vector<Anchor> anchors;
  std::vector<std::size_t> lines;
  forEachRow(csv, [&] {
    Anchor a;
    a.id = csv.requiredUint32(c_id);
    a.p_w_anchor = requiredVec3(csv, c_x, c_y, c_z);
    const std::string_view kind = csv.field(c_kind);
    if (!kind.empty()) {
      const std::optional<AnchorKind> k = anchorKindFromString(kind);
      if (!k) csv.fail(c_kind, quoteField(kind) + " is not an anchor kind (uwb, ultrasonic)");
      a.kind = *k;
    }
    a.sigma_m = csv.optionalDouble(c_sigma);
    if (a.sigma_m && *a.sigma_m < 0.0) csv.fail(c_sigma, "negative standard deviation");
    for (std::size_t k = 0; k < anchors.size(); ++k) {
      if (anchors[k].id == a.id) {
        csv.fail(c_id, "anchor id " + std::to_string(a.id) + " already defined on line " + std::to_string(lines[k]));
      }
    }
    anchors.push_back(a);
    lines.push_back(csv.line());
  });
  return anchors;
}

std::vector<Tag> parseTags(std::string_view text, const std::string& file, ReadReport& report) {
  CsvReader csv = openCsv(text, file, kTagsRequired, kTagsOptional, false, report);
  const int c_id = csv.column("id"), c_x = csv.column("x"), c_y = csv.column("y"), c_z = csv.column("z");
  std::vector<Tag> tags;
  std::vector<std::size_t> lines;
  forEachRow(csv, [&] {
    Tag t;
    t.id = csv.requiredUint32(c_id);
    t.p_b_tag = requiredVec3(csv, c_x, c_y, c_z);
    for (std::size_t k = 0; k < tags.size(); ++k) {
      if (tags[k].id == t.id) {
        csv.fail(c_id, "tag id " + std::to_string(t.id) + " already defined on line " + std::to_string(lines[k]));
      }
    }
    tags.push_back(t);
    lines.push_back(csv.line());
  });
  return tags;
}

void parseImu(std::string_view text, const std::string& file, std::vector<ImuSample>& imu,
              std::vector<double>& temp_c, ReadReport& report) {
  imu.clear();
  temp_c.clear();
  CsvReader csv = openCsv(text, file, kImuRequired, kImuOptional, true, report);
  const int c_t = csv.column("t_ns");
  const int c_wx = csv.column("wx"), c_wy = csv.column("wy"), c_wz = csv.column("wz");
  const int c_ax = csv.column("ax"), c_ay = csv.column("ay"), c_az = csv.column("az");
  const int c_temp = csv.column("temp_c");
  const bool has_temp = c_temp != kAbsent;
  imu.reserve(static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n')) + 1);  // rows <= lines
  if (has_temp) temp_c.reserve(imu.capacity());
  std::size_t prev_line = 0;
  forEachRow(csv, [&] {
    ImuSample s;
    s.t_ns = csv.requiredInt64(c_t);
    s.gyro_rad_s = requiredVec3(csv, c_wx, c_wy, c_wz);
    s.accel_m_s2 = requiredVec3(csv, c_ax, c_ay, c_az);
    const double temp = has_temp ? csv.optionalDouble(c_temp).value_or(kNaN) : kNaN;
    const bool keep = admitStrict(csv, c_t, imu, prev_line, s, [&](const ImuSample& a, const ImuSample& b) {
      return a.gyro_rad_s == b.gyro_rad_s && a.accel_m_s2 == b.accel_m_s2 &&
             (!has_temp || sameDouble(temp_c.back(), temp));
    });
    if (!keep) return;
    imu.push_back(s);
    if (has_temp) temp_c.push_back(temp);
    prev_line = csv.line();
  });
}

std::vector<RangeSample> parseRanges(std::string_view text, const std::string& file,
                                     const std::vector<Anchor>& anchors, const std::vector<Tag>& tags,
                                     ReadReport& report) {
  CsvReader csv = openCsv(text, file, kRangeRequired, kRangeOptional, false, report);
  const int c_t = csv.column("t_ns"), c_anchor = csv.column("anchor_id"), c_range = csv.column("range_m");
  const int c_tag = csv.column("tag_id"), c_rssi = csv.column("rssi_dbm"), c_fp = csv.column("fp_power_dbm");
  const int c_los = csv.column("los");
  const AnchorLookup lookup(anchors);
  std::vector<RangeSample> out;
  EventOrder<RangeSample> order;
  forEachRow(csv, [&] {
    RangeSample s;
    s.t_ns = csv.requiredInt64(c_t);
    s.anchor_id = csv.requiredUint32(c_anchor);
    s.range_m = csv.requiredDouble(c_range);
    s.tag_id = csv.optionalUint32(c_tag).value_or(0);
    s.rssi_dbm = csv.optionalDouble(c_rssi).value_or(kNaN);
    s.fp_power_dbm = csv.optionalDouble(c_fp).value_or(kNaN);
    s.los = parseLos(csv, c_los);
    lookup.check(csv, c_anchor, s.anchor_id, AnchorKind::kUwb);
    bool tag_known = tags.empty() && s.tag_id == 0;
    for (const Tag& t : tags) tag_known = tag_known || t.id == s.tag_id;
    if (!tag_known) {
      csv.fail(c_tag, "tag " + std::to_string(s.tag_id) +
                          (tags.empty() ? " is unknown (without tags.csv only tag 0 exists)" : " is not in tags.csv"));
    }
    const bool keep = order.admit(
        csv, c_t, out, s,
        [](const RangeSample& a, const RangeSample& b) { return a.anchor_id == b.anchor_id && a.tag_id == b.tag_id; },
        [](const RangeSample& a, const RangeSample& b) {
          return a.range_m == b.range_m && sameDouble(a.rssi_dbm, b.rssi_dbm) &&
                 sameDouble(a.fp_power_dbm, b.fp_power_dbm) && a.los == b.los;
        });
    if (!keep) return;
    out.push_back(s);
    order.pushed(csv.line());
  });
  return out;
}

std::vector<TdoaSample> parseTdoa(std::string_view text, const std::string& file,
                                  const std::vector<Anchor>& anchors, ReadReport& report) {
  CsvReader csv = openCsv(text, file, kTdoaRequired, kTdoaOptional, false, report);
  const int c_t = csv.column("t_ns"), c_a = csv.column("anchor_a"), c_b = csv.column("anchor_b");
  const int c_diff = csv.column("diff_m"), c_los = csv.column("los");
  const int c_rssi_a = csv.column("rssi_a_dbm"), c_fp_a = csv.column("fp_power_a_dbm");
  const int c_rssi_b = csv.column("rssi_b_dbm"), c_fp_b = csv.column("fp_power_b_dbm");
  const AnchorLookup lookup(anchors);
  std::vector<TdoaSample> out;
  EventOrder<TdoaSample> order;
  forEachRow(csv, [&] {
    TdoaSample s;
    s.t_ns = csv.requiredInt64(c_t);
    s.anchor_a = csv.requiredUint32(c_a);
    s.anchor_b = csv.requiredUint32(c_b);
    s.diff_m = csv.requiredDouble(c_diff);
    s.rssi_a_dbm = csv.optionalDouble(c_rssi_a).value_or(kNaN);
    s.fp_power_a_dbm = csv.optionalDouble(c_fp_a).value_or(kNaN);
    s.rssi_b_dbm = csv.optionalDouble(c_rssi_b).value_or(kNaN);
    s.fp_power_b_dbm = csv.optionalDouble(c_fp_b).value_or(kNaN);
    s.los = parseLos(csv, c_los);
    lookup.check(csv, c_a, s.anchor_a, AnchorKind::kUwb);
    lookup.check(csv, c_b, s.anchor_b, AnchorKind::kUwb);
    if (s.anchor_a == s.anchor_b) csv.fail(c_b, "anchor_b equals anchor_a (" + std::to_string(s.anchor_a) + ")");
    const bool keep = order.admit(
        csv, c_t, out, s,
        [](const TdoaSample& a, const TdoaSample& b) { return a.anchor_a == b.anchor_a && a.anchor_b == b.anchor_b; },
        [](const TdoaSample& a, const TdoaSample& b) {
          return a.diff_m == b.diff_m && sameDouble(a.rssi_a_dbm, b.rssi_a_dbm) &&
                 sameDouble(a.fp_power_a_dbm, b.fp_power_a_dbm) && sameDouble(a.rssi_b_dbm, b.rssi_b_dbm) &&
                 sameDouble(a.fp_power_b_dbm, b.fp_power_b_dbm) && a.los == b.los;
        });
    if (!keep) return;
    out.push_back(s);
    order.pushed(csv.line());
  });
  return out;
}

std::vector<UltrasonicSample> parseUltrasonic(std::string_view text, const std::string& file,
                                              const std::vector<Anchor>& anchors, ReadReport& report) {
  CsvReader csv = openCsv(text, file, kUltrasonicRequired, kUltrasonicOptional, false, report);
  const int c_t = csv.column("t_ns"), c_anchor = csv.column("anchor_id"), c_range = csv.column("range_m");
  const int c_los = csv.column("los");
  const AnchorLookup lookup(anchors);
  std::vector<UltrasonicSample> out;
  EventOrder<UltrasonicSample> order;
  forEachRow(csv, [&] {
    UltrasonicSample s;
    s.t_ns = csv.requiredInt64(c_t);
    s.anchor_id = csv.requiredUint32(c_anchor);
    s.range_m = csv.requiredDouble(c_range);
    s.los = parseLos(csv, c_los);
    lookup.check(csv, c_anchor, s.anchor_id, AnchorKind::kUltrasonic);
    const bool keep = order.admit(
        csv, c_t, out, s, [](const UltrasonicSample& a, const UltrasonicSample& b) { return a.anchor_id == b.anchor_id; },
        [](const UltrasonicSample& a, const UltrasonicSample& b) { return a.range_m == b.range_m && a.los == b.los; });
    if (!keep) return;
    out.push_back(s);
    order.pushed(csv.line());
  });
  return out;
}

std::vector<GroundTruthPose> parseGroundTruth(std::string_view text, const std::string& file, ReadReport& report) {
  CsvReader csv = openCsv(text, file, kGroundTruthRequired, kGroundTruthOptional, false, report);
  const int c_t = csv.column("t_ns");
  const int c_px = csv.column("px"), c_py = csv.column("py"), c_pz = csv.column("pz");
  const int c_qw = csv.column("qw"), c_qx = csv.column("qx"), c_qy = csv.column("qy"), c_qz = csv.column("qz");
  const int c_vx = csv.column("vx"), c_vy = csv.column("vy"), c_vz = csv.column("vz");
  const int n_vel = (c_vx != kAbsent) + (c_vy != kAbsent) + (c_vz != kAbsent);
  if (n_vel != 0 && n_vel != 3) {
    const char* missing = c_vx == kAbsent ? "vx" : (c_vy == kAbsent ? "vy" : "vz");
    throw RecordingError(file, csv.headerLine(), missing, "vx, vy, vz must be given together");
  }
  std::vector<GroundTruthPose> out;
  std::size_t prev_line = 0;
  forEachRow(csv, [&] {
    GroundTruthPose g;
    g.t_ns = csv.requiredInt64(c_t);
    g.p_w_b = requiredVec3(csv, c_px, c_py, c_pz);
    g.q_w_b = Quat(csv.requiredDouble(c_qw), csv.requiredDouble(c_qx), csv.requiredDouble(c_qy),
                   csv.requiredDouble(c_qz));
    const double norm = g.q_w_b.norm();
    if (!(std::abs(norm - 1.0) <= kQuaternionNormTolerance)) {
      csv.fail(c_qw, "quaternion (qw, qx, qy, qz) has norm " + std::to_string(norm) + ", expected 1");
    }
    if (n_vel == 3) {
      const std::optional<double> vx = csv.optionalDouble(c_vx), vy = csv.optionalDouble(c_vy),
                                  vz = csv.optionalDouble(c_vz);
      if (vx && vy && vz) {
        g.v_w_b = Vec3(*vx, *vy, *vz);
      } else if (vx || vy || vz) {
        csv.fail(!vx ? c_vx : (!vy ? c_vy : c_vz), "empty while other velocity components are given");
      }
    }
    const bool keep = admitStrict(csv, c_t, out, prev_line, g, [](const GroundTruthPose& a, const GroundTruthPose& b) {
      return a.p_w_b == b.p_w_b && a.q_w_b.coeffs() == b.q_w_b.coeffs() && a.v_w_b.has_value() == b.v_w_b.has_value() &&
             (!a.v_w_b || *a.v_w_b == *b.v_w_b);
    });
    if (!keep) return;
    out.push_back(g);
    prev_line = csv.line();
  });
  return out;
}

}  // namespace recording

namespace {

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

/// Whole file as text, or nullopt if it does not exist.
std::optional<std::string> readFileText(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (st.type() == std::filesystem::file_type::not_found) return std::nullopt;
  if (ec) throw RecordingError(path.string(), 0, "", "cannot stat: " + ec.message());
  if (st.type() != std::filesystem::file_type::regular) throw RecordingError(path.string(), 0, "", "not a regular file");
  std::unique_ptr<std::FILE, FileCloser> f(std::fopen(path.c_str(), "rb"));
  if (!f) throw RecordingError(path.string(), 0, "", std::string("cannot open: ") + std::strerror(errno));
  std::string text;
  const std::uintmax_t size_hint = std::filesystem::file_size(path, ec);
  if (!ec) text.reserve(static_cast<std::size_t>(size_hint));
  char buf[1 << 16];
  while (true) {
    const std::size_t n = std::fread(buf, 1, sizeof(buf), f.get());
    text.append(buf, n);
    if (n < sizeof(buf)) break;
  }
  if (std::ferror(f.get())) throw RecordingError(path.string(), 0, "", "read error");
  return text;
}

}  // namespace

Recording readRecording(const std::filesystem::path& dir, ReadReport* report) {
  ReadReport local;
  ReadReport& rep = report != nullptr ? *report : local;
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) throw RecordingError(dir.string(), 0, "", "not a recording folder");

  auto path = [&](std::string_view name) { return (dir / name).string(); };
  auto required = [&](std::string_view name) {
    std::optional<std::string> text = readFileText(dir / name);
    if (!text) throw RecordingError(path(name), 0, "", "required file missing");
    return std::move(*text);
  };

  Recording rec;
  if (const auto meta = readFileText(dir / recording::kMetaFile)) {
    rec.meta = recording::parseMetaYaml(*meta, path(recording::kMetaFile), rep);
  }
  rec.anchors = recording::parseAnchors(required(recording::kAnchorsFile), path(recording::kAnchorsFile), rep);
  if (const auto t = readFileText(dir / recording::kTagsFile)) {
    rec.tags = recording::parseTags(*t, path(recording::kTagsFile), rep);
  }
  recording::parseImu(required(recording::kImuFile), path(recording::kImuFile), rec.imu, rec.imu_temp_c, rep);
  if (const auto t = readFileText(dir / recording::kRangeFile)) {
    rec.ranges = recording::parseRanges(*t, path(recording::kRangeFile), rec.anchors, rec.tags, rep);
  }
  if (const auto t = readFileText(dir / recording::kTdoaFile)) {
    rec.tdoa = recording::parseTdoa(*t, path(recording::kTdoaFile), rec.anchors, rep);
  }
  if (const auto t = readFileText(dir / recording::kUltrasonicFile)) {
    rec.ultrasonic = recording::parseUltrasonic(*t, path(recording::kUltrasonicFile), rec.anchors, rep);
  }
  if (const auto t = readFileText(dir / recording::kGroundTruthFile)) {
    rec.groundtruth = recording::parseGroundTruth(*t, path(recording::kGroundTruthFile), rep);
  }
  return rec;
}

}  // namespace rilo
