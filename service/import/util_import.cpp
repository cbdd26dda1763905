#include "import/util_import.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <numbers>
#include <span>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "hal/recording/csv_parser.h"
#include "hal/recording/number_text.h"
#include "hal/recording/recording_files.h"
#include "hal/recording/recording_writer.h"

namespace rilo::importer {
namespace {

using recording::CsvReader;

// Columns of a flight CSV (log_to_csv.py of the dataset; docs/util-dataset.md).
constexpr std::string_view kTdoaColumns[] = {"t_tdoa", "idA", "idB", "tdoa_meas"};
constexpr std::string_view kAccelColumns[] = {"t_acc", "acc_x", "acc_y", "acc_z"};
constexpr std::string_view kGyroColumns[] = {"t_gyro", "gyro_x", "gyro_y", "gyro_z"};
constexpr std::string_view kPoseColumns[] = {"t_pose", "pose_x", "pose_y", "pose_z",
                                             "pose_qx", "pose_qy", "pose_qz", "pose_qw"};
constexpr std::string_view kRequired[] = {
    "t_tdoa", "idA",    "idB",    "tdoa_meas", "t_acc",  "acc_x",  "acc_y",   "acc_z",   "t_gyro",  "gyro_x",
    "gyro_y", "gyro_z", "t_pose", "pose_x",    "pose_y", "pose_z", "pose_qx", "pose_qy", "pose_qz", "pose_qw"};
/// Recognised but not imported (rilo has no ToF, flow or barometer stream).
constexpr std::string_view kOptional[] = {"t_tof", "tof", "t_flow", "deltaX", "deltaY", "t_baro", "baro"};

/// Largest |t| in seconds whose t_ns fits an int64 with margin.
constexpr double kMaxAbsTimeS = 9.0e9;

std::string seconds(std::int64_t t_ns) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.6f s", static_cast<double>(t_ns) * 1e-9);
  return buf;
}

std::string fixed(double v, int decimals) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals, v);
  return buf;
}

/// One sample as parsed, before unit conversion (kept for duplicate detection).
struct RawSample {
  std::int64_t t_ns = 0;
  std::array<double, 7> v{};
  std::size_t line = 0;
};

/// Column indices of one stream block.
template <std::size_t N>
std::array<int, N> columnsOf(const CsvReader& r, const std::string_view (&names)[N]) {
  std::array<int, N> cols{};
  for (std::size_t i = 0; i < N; ++i) cols[i] = r.column(names[i]);
  return cols;
}

/// True if the row holds a sample of the block, false if the block is empty
/// (the stream has ended: zip_longest padding). A partly filled block is an error.
bool blockPresent(const CsvReader& r, std::span<const int> cols) {
  int first_empty = CsvReader::kAbsent;
  int first_set = CsvReader::kAbsent;
  for (const int c : cols) {
    if (r.field(c).empty()) {
      if (first_empty == CsvReader::kAbsent) first_empty = c;
    } else if (first_set == CsvReader::kAbsent) {
      first_set = c;
    }
  }
  if (first_set == CsvReader::kAbsent) return false;
  if (first_empty != CsvReader::kAbsent) {
    r.fail(first_empty, "empty while other fields of the same sample are set (a sample fills all of " +
                            std::to_string(cols.size()) + " columns of its block, or none)");
  }
  return true;
}

std::int64_t timeNs(const CsvReader& r, int col) {
  const double t_s = r.requiredDouble(col);
  if (!(std::abs(t_s) <= kMaxAbsTimeS)) r.fail(col, "time " + std::to_string(t_s) + " s is out of range");
  return static_cast<std::int64_t>(std::llround(t_s * 1e9));
}

/// Anchor id written as a float by the dataset's converter ("7.0").
std::uint32_t anchorId(const CsvReader& r, int col) {
  const double v = r.requiredDouble(col);
  if (!(v >= 0.0 && v <= 4294967295.0 && v == std::floor(v))) {
    r.fail(col, recording::quoteField(r.field(col)) + " is not an anchor id (a non-negative integer)");
  }
  return static_cast<std::uint32_t>(v);
}

/// Keeps a stream in time order: appends a sample, drops a duplicate of the
/// previous one (counted), and fails on (or with drop_unordered drops and
/// counts) a sample out of order. `keyed`: samples at the same time are
/// distinct if v[0], v[1] (the anchor pair) differ.
class StreamBuilder {
 public:
  StreamBuilder(StreamCounts& counts, bool keyed, bool drop_unordered)
      : counts_(counts), keyed_(keyed), drop_unordered_(drop_unordered) {}

  void add(const CsvReader& r, int t_col, const RawSample& s) {
    ++counts_.rows;
    if (!samples_.empty()) {
      const RawSample& last = samples_.back();
      if (s.t_ns < last.t_ns) {
        return unordered(r, t_col, s,
                         "time " + seconds(s.t_ns) + " is earlier than " + seconds(last.t_ns) + " of the sample on line " +
                             std::to_string(last.line) + " (samples must be in time order)");
      }
      if (s.t_ns == last.t_ns) {
        const RawSample* same = &last;
        if (keyed_) {
          same = nullptr;
          for (auto it = samples_.rbegin(); it != samples_.rend() && it->t_ns == s.t_ns; ++it) {
            if (it->v[0] == s.v[0] && it->v[1] == s.v[1]) {
              same = &*it;
              break;
            }
          }
        }
        if (same != nullptr) {
          if (same->v == s.v) {
            ++counts_.duplicates;
            if (counts_.first_duplicate_line == 0) counts_.first_duplicate_line = s.line;
            return;
          }
          return unordered(r, t_col, s,
                           "same time " + seconds(s.t_ns) + (keyed_ ? " and anchor pair" : "") + " as line " +
                               std::to_string(same->line) + " but different values");
        }
      }
    }
    samples_.push_back(s);
    ++counts_.kept;
  }

  const std::vector<RawSample>& samples() const { return samples_; }

 private:
  void unordered(const CsvReader& r, int t_col, const RawSample& s, const std::string& detail) {
    if (!drop_unordered_) r.fail(t_col, detail);
    ++counts_.unordered;
    if (counts_.first_unordered_line == 0) counts_.first_unordered_line = s.line;
  }

  StreamCounts& counts_;
  bool keyed_;
  bool drop_unordered_;
  std::vector<RawSample> samples_;
};

void checkOptions(const UtilImportOptions& o) {
  if (!(std::isfinite(o.gravity_m_s2) && o.gravity_m_s2 > 0.0)) {
    throw std::invalid_argument("gravity_m_s2 must be finite and > 0, got " + std::to_string(o.gravity_m_s2));
  }
  if (!o.lever_arm_m.allFinite()) throw std::invalid_argument("lever_arm_m must be finite");
  if (!(std::isfinite(o.max_imu_gap_s) && o.max_imu_gap_s > 0.0)) {
    throw std::invalid_argument("max_imu_gap_s must be finite and > 0, got " + std::to_string(o.max_imu_gap_s));
  }
}

/// IMU samples at the clock stream's times, the other stream interpolated
/// linearly between neighbours no further apart than max_gap_ns.
std::vector<ImuSample> combineImu(const std::vector<RawSample>& gyro, const std::vector<RawSample>& accel,
                                  const UtilImportOptions& o, std::size_t& without_partner) {
  const double gyro_scale = o.gyro_unit == GyroUnit::kDegPerSecond ? std::numbers::pi / 180.0 : 1.0;
  const double accel_scale = o.accel_unit == AccelUnit::kG ? o.gravity_m_s2 : 1.0;
  const bool gyro_clock = o.imu_clock == ImuClock::kGyro;
  const std::vector<RawSample>& clock = gyro_clock ? gyro : accel;
  const std::vector<RawSample>& other = gyro_clock ? accel : gyro;
  const std::int64_t max_gap_ns = std::llround(o.max_imu_gap_s * 1e9);
  const auto vec = [](const RawSample& s) { return Vec3(s.v[0], s.v[1], s.v[2]); };

  std::vector<ImuSample> imu;
  imu.reserve(clock.size());
  std::size_t j = 0;
  for (const RawSample& c : clock) {
    while (j + 1 < other.size() && other[j + 1].t_ns <= c.t_ns) ++j;
    Vec3 partner;
    if (!other.empty() && other[j].t_ns == c.t_ns) {
      partner = vec(other[j]);
    } else if (!other.empty() && other[j].t_ns < c.t_ns && j + 1 < other.size() &&
               other[j + 1].t_ns - other[j].t_ns <= max_gap_ns) {
      const double s = static_cast<double>(c.t_ns - other[j].t_ns) /
                       static_cast<double>(other[j + 1].t_ns - other[j].t_ns);
      partner = (1.0 - s) * vec(other[j]) + s * vec(other[j + 1]);
    } else {
      ++without_partner;
      continue;
    }
    ImuSample sample;
    sample.t_ns = c.t_ns;
    sample.gyro_rad_s = gyro_scale * (gyro_clock ? vec(c) : partner);
    sample.accel_m_s2 = accel_scale * (gyro_clock ? partner : vec(c));
    imu.push_back(sample);
  }
  return imu;
}

std::optional<double> medianRateHz(const std::vector<ImuSample>& imu) {
  if (imu.size() < 2) return std::nullopt;
  std::vector<std::int64_t> dt;
  dt.reserve(imu.size() - 1);
  for (std::size_t i = 1; i < imu.size(); ++i) dt.push_back(imu[i].t_ns - imu[i - 1].t_ns);
  const auto mid = dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2);
  std::nth_element(dt.begin(), mid, dt.end());
  if (*mid <= 0) return std::nullopt;
  return 1e9 / static_cast<double>(*mid);
}

std::string readWholeFile(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw RecordingError(path.string(), 0, "", "cannot open the file");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) throw RecordingError(path.string(), 0, "", "read error");
  return ss.str();
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

std::string pairText(std::uint32_t a, std::uint32_t b) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "(%u, %u)", a, b);
  return buf;
}

}  // namespace

std::string_view toString(AccelUnit unit) { return unit == AccelUnit::kG ? "g" : "m/s2"; }
std::string_view toString(GyroUnit unit) { return unit == GyroUnit::kDegPerSecond ? "deg/s" : "rad/s"; }
std::string_view toString(TdoaSign sign) { return sign == TdoaSign::kBMinusA ? "b-minus-a" : "a-minus-b"; }
std::string_view toString(ImuClock clock) { return clock == ImuClock::kGyro ? "gyro" : "accel"; }
std::string_view toString(CheckStatus status) {
  switch (status) {
    case CheckStatus::kOk: return "ok";
    case CheckStatus::kContradiction: return "CONTRADICTS";
    case CheckStatus::kInconclusive: return "warning";
  }
  return "?";
}

std::optional<AccelUnit> accelUnitFromString(std::string_view text) {
  if (text == "g") return AccelUnit::kG;
  if (text == "m/s2" || text == "m/s^2") return AccelUnit::kMetersPerSecond2;
  return std::nullopt;
}
std::optional<GyroUnit> gyroUnitFromString(std::string_view text) {
  if (text == "deg/s") return GyroUnit::kDegPerSecond;
  if (text == "rad/s") return GyroUnit::kRadPerSecond;
  return std::nullopt;
}
std::optional<TdoaSign> tdoaSignFromString(std::string_view text) {
  if (text == "b-minus-a") return TdoaSign::kBMinusA;
  if (text == "a-minus-b") return TdoaSign::kAMinusB;
  return std::nullopt;
}
std::optional<ImuClock> imuClockFromString(std::string_view text) {
  if (text == "gyro") return ImuClock::kGyro;
  if (text == "accel") return ImuClock::kAccel;
  return std::nullopt;
}

UtilSurvey parseUtilSurvey(std::string_view text, const std::string& file) {
  UtilSurvey survey;
  survey.file = file;
  std::vector<std::size_t> position_line;  // parallel to survey.anchors
  struct QuatLine {
    std::uint32_t id;
    std::size_t line;
  };
  std::vector<QuatLine> quats;

  std::size_t line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    const std::size_t nl = text.find('\n', pos);
    std::string_view line = text.substr(pos, nl == std::string_view::npos ? std::string_view::npos : nl - pos);
    pos = nl == std::string_view::npos ? text.size() : nl + 1;
    ++line_no;
    line = trim(line);
    if (line.empty() || line.front() == '#') continue;

    std::vector<std::string_view> fields;
    for (std::size_t start = 0;;) {
      const std::size_t comma = line.find(',', start);
      fields.push_back(trim(line.substr(start, comma == std::string_view::npos ? std::string_view::npos : comma - start)));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    const std::string_view key = fields[0];
    const std::size_t underscore = key.find('_');
    std::uint32_t id = 0;
    const std::string_view suffix = underscore == std::string_view::npos ? std::string_view() : key.substr(underscore);
    const bool id_ok = key.size() > 2 && key.substr(0, 2) == "an" && underscore != std::string_view::npos &&
                       recording::parseUint32(key.substr(2, underscore - 2), id) == recording::NumberStatus::kOk;
    if (!id_ok || (suffix != "_p" && suffix != "_quat")) {
      throw RecordingError(file, line_no, "", "expected 'anN_p,x,y,z' or 'anN_quat,qx,qy,qz,qw', found key " +
                                                  recording::quoteField(key));
    }
    const bool is_position = suffix == "_p";
    static constexpr std::string_view kPositionNames[] = {"x", "y", "z"};
    static constexpr std::string_view kQuatNames[] = {"qx", "qy", "qz", "qw"};
    const std::span<const std::string_view> names = is_position ? std::span<const std::string_view>(kPositionNames)
                                                                : std::span<const std::string_view>(kQuatNames);
    if (fields.size() != names.size() + 1) {
      throw RecordingError(file, line_no, std::string(key),
                           "expected " + std::to_string(names.size()) + " numbers after the key, found " +
                               std::to_string(fields.size() - 1));
    }
    std::array<double, 4> v{};
    for (std::size_t i = 0; i < names.size(); ++i) {
      const recording::NumberStatus s = recording::parseDouble(fields[i + 1], v[i]);
      if (s != recording::NumberStatus::kOk) {
        throw RecordingError(file, line_no, std::string(names[i]),
                             recording::describeNumberStatus(s, fields[i + 1], "a number"));
      }
    }
    if (is_position) {
      for (std::size_t k = 0; k < survey.anchors.size(); ++k) {
        if (survey.anchors[k].id == id) {
          throw RecordingError(file, line_no, std::string(key),
                               "anchor " + std::to_string(id) + " already has a position on line " +
                                   std::to_string(position_line[k]));
        }
      }
      Anchor a;
      a.id = id;
      a.p_w_anchor = Vec3(v[0], v[1], v[2]);
      a.kind = AnchorKind::kUwb;
      survey.anchors.push_back(a);
      position_line.push_back(line_no);
    } else {
      for (const QuatLine& q : quats) {
        if (q.id == id) {
          throw RecordingError(file, line_no, std::string(key),
                               "anchor " + std::to_string(id) + " already has an orientation on line " +
                                   std::to_string(q.line));
        }
      }
      const double norm = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]);
      if (!(std::abs(norm - 1.0) <= recording::kQuaternionNormTolerance)) {
        throw RecordingError(file, line_no, std::string(key),
                             "quaternion norm " + fixed(norm, 6) + " is not 1 (order qx,qy,qz,qw)");
      }
      quats.push_back({id, line_no});
    }
  }
  for (const QuatLine& q : quats) {
    const bool has_position = std::any_of(survey.anchors.begin(), survey.anchors.end(),
                                          [&](const Anchor& a) { return a.id == q.id; });
    if (!has_position) {
      throw RecordingError(file, q.line, "", "orientation of anchor " + std::to_string(q.id) + " without an an" +
                                                 std::to_string(q.id) + "_p position line");
    }
  }
  if (survey.anchors.empty()) throw RecordingError(file, 0, "", "no anchor position (anN_p lines)");
  std::sort(survey.anchors.begin(), survey.anchors.end(), [](const Anchor& x, const Anchor& y) { return x.id < y.id; });
  survey.orientations = quats.size();
  return survey;
}

UtilImport parseUtilFlight(std::string_view text, const std::string& file, const UtilSurvey& survey,
                           const UtilImportOptions& options) {
  checkOptions(options);
  UtilImport out;
  out.flight_file = file;
  out.survey_file = survey.file;
  out.options = options;
  out.survey_orientations = survey.orientations;

  CsvReader r(text, file, kRequired, kOptional, out.report);
  if (!r.hasHeader()) throw RecordingError(file, 0, "", "no header line (empty file)");
  const auto tdoa_cols = columnsOf(r, kTdoaColumns);
  const auto accel_cols = columnsOf(r, kAccelColumns);
  const auto gyro_cols = columnsOf(r, kGyroColumns);
  const auto pose_cols = columnsOf(r, kPoseColumns);
  const auto knownAnchor = [&](std::uint32_t id) {
    return std::any_of(survey.anchors.begin(), survey.anchors.end(), [&](const Anchor& a) { return a.id == id; });
  };

  StreamBuilder tdoa(out.tdoa, true, options.drop_unordered);
  StreamBuilder accel(out.accel, false, options.drop_unordered);
  StreamBuilder gyro(out.gyro, false, options.drop_unordered);
  StreamBuilder pose(out.pose, false, options.drop_unordered);

  while (r.next()) {
    if (blockPresent(r, tdoa_cols)) {
      RawSample s;
      s.line = r.line();
      s.t_ns = timeNs(r, tdoa_cols[0]);
      const std::uint32_t id_a = anchorId(r, tdoa_cols[1]);
      const std::uint32_t id_b = anchorId(r, tdoa_cols[2]);
      if (!knownAnchor(id_a)) r.fail(tdoa_cols[1], "anchor " + std::to_string(id_a) + " is not in " + survey.file);
      if (!knownAnchor(id_b)) r.fail(tdoa_cols[2], "anchor " + std::to_string(id_b) + " is not in " + survey.file);
      if (id_a == id_b) r.fail(tdoa_cols[2], "idB equals idA (" + std::to_string(id_a) + ")");
      s.v[0] = id_a;
      s.v[1] = id_b;
      s.v[2] = r.requiredDouble(tdoa_cols[3]);
      tdoa.add(r, tdoa_cols[0], s);
    }
    for (auto* stream : {&accel, &gyro}) {
      const auto& cols = stream == &accel ? accel_cols : gyro_cols;
      if (!blockPresent(r, cols)) continue;
      RawSample s;
      s.line = r.line();
      s.t_ns = timeNs(r, cols[0]);
      for (int i = 0; i < 3; ++i) s.v[static_cast<std::size_t>(i)] = r.requiredDouble(cols[static_cast<std::size_t>(i) + 1]);
      stream->add(r, cols[0], s);
    }
    if (blockPresent(r, pose_cols)) {
      RawSample s;
      s.line = r.line();
      s.t_ns = timeNs(r, pose_cols[0]);
      for (std::size_t i = 0; i < 7; ++i) s.v[i] = r.requiredDouble(pose_cols[i + 1]);
      const double norm = Eigen::Vector4d(s.v[3], s.v[4], s.v[5], s.v[6]).norm();
      if (!(std::abs(norm - 1.0) <= recording::kQuaternionNormTolerance)) {
        r.fail(pose_cols[4], "quaternion (pose_qx, pose_qy, pose_qz, pose_qw) has norm " + fixed(norm, 6) +
                                 ", not 1");
      }
      pose.add(r, pose_cols[0], s);
    }
  }

  if (tdoa.samples().empty()) throw RecordingError(file, 0, "t_tdoa", "no TDoA sample in the file");
  if (accel.samples().empty()) throw RecordingError(file, 0, "t_acc", "no accelerometer sample in the file");
  if (gyro.samples().empty()) throw RecordingError(file, 0, "t_gyro", "no gyroscope sample in the file");
  if (pose.samples().empty()) out.report.warn(file, 0, "t_pose", "no Vicon pose: the recording has no ground truth");

  Recording& rec = out.recording;
  rec.anchors = survey.anchors;
  rec.imu = combineImu(gyro.samples(), accel.samples(), options, out.imu_without_partner);
  if (rec.imu.empty()) {
    throw RecordingError(file, 0, "", "no IMU sample: the accelerometer and gyroscope times do not overlap");
  }
  const double sign = options.tdoa_sign == TdoaSign::kBMinusA ? 1.0 : -1.0;
  rec.tdoa.reserve(tdoa.samples().size());
  for (const RawSample& s : tdoa.samples()) {
    TdoaSample t;
    t.t_ns = s.t_ns;
    t.anchor_a = static_cast<std::uint32_t>(s.v[0]);
    t.anchor_b = static_cast<std::uint32_t>(s.v[1]);
    t.diff_m = sign * s.v[2];
    rec.tdoa.push_back(t);
  }
  rec.groundtruth.reserve(pose.samples().size());
  for (const RawSample& s : pose.samples()) {
    GroundTruthPose g;
    g.t_ns = s.t_ns;
    g.p_w_b = Vec3(s.v[0], s.v[1], s.v[2]);
    g.q_w_b = Quat(s.v[6], s.v[3], s.v[4], s.v[5]).normalized();  // file order x, y, z, w
    rec.groundtruth.push_back(g);
  }

  RecordingMeta& meta = rec.meta;
  meta.name = std::filesystem::path(file).stem().string();
  meta.description = "UTIL dataset flight " + file + " with anchor survey " + survey.file +
                     ", imported by rilo import-util (accel " + std::string(toString(options.accel_unit)) + ", gyro " +
                     std::string(toString(options.gyro_unit)) + ", tdoa " + std::string(toString(options.tdoa_sign)) +
                     ", imu clock " + std::string(toString(options.imu_clock)) + ")";
  meta.gravity_m_s2 = options.gravity_m_s2;
  meta.imu_rate_hz = medianRateHz(rec.imu);
  meta.uwb_lever_arm_m = options.lever_arm_m;
  meta.ranging = RangingKind::kTdoa;
  return out;
}

UtilImport importUtil(const std::filesystem::path& flight_csv, const std::filesystem::path& survey_txt,
                      const UtilImportOptions& options) {
  const std::string survey_text = readWholeFile(survey_txt);
  const UtilSurvey survey = parseUtilSurvey(survey_text, survey_txt.string());
  const std::string flight_text = readWholeFile(flight_csv);
  return parseUtilFlight(flight_text, flight_csv.string(), survey, options);
}

void writeUtilRecording(const UtilImport& imported, const std::filesystem::path& dir, bool overwrite) {
  RecordingWriterOptions options;
  options.overwrite = overwrite;
  writeRecording(dir, imported.recording, options);
}

std::vector<CheckVerdict> judgeUtilPhysics(const PhysicsCheck& check, const UtilImportOptions& options) {
  std::vector<CheckVerdict> verdicts;
  const auto near = [](double value, double target, double factor) {
    return std::isfinite(value) && value > 0.0 && value >= target / factor && value <= target * factor;
  };

  {  // Accelerometer: the wrong unit shows as a factor g (or 1/g) in median |a| / g.
    CheckVerdict v;
    v.item = "accel unit";
    const AccelCheck& a = check.accel;
    const bool chose_g = options.accel_unit == AccelUnit::kG;
    const double wrong_factor = chose_g ? options.gravity_m_s2 : 1.0 / options.gravity_m_s2;
    const AccelUnit other = chose_g ? AccelUnit::kMetersPerSecond2 : AccelUnit::kG;
    const std::string figures = "median |a| " + fixed(a.median_norm_m_s2, 3) + " m/s^2 = " + fixed(a.ratio_to_gravity, 3) +
                                " g over " + std::to_string(a.samples) + " samples";
    if (a.samples == 0) {
      v.message = "no IMU sample to check";
    } else if (near(a.ratio_to_gravity, 1.0, 1.25)) {
      v.status = CheckStatus::kOk;
      v.message = figures + " (--accel-unit " + std::string(toString(options.accel_unit)) + ")";
    } else if (near(a.ratio_to_gravity, wrong_factor, 1.5)) {
      v.status = CheckStatus::kContradiction;
      v.message = figures + ": with --accel-unit " + std::string(toString(options.accel_unit)) +
                  " the accelerometer reads " + fixed(a.ratio_to_gravity, 2) +
                  " times gravity; the file's unit is " + std::string(toString(other)) + ": use --accel-unit " +
                  std::string(toString(other));
    } else {
      v.message = figures + ": not near gravity for either unit (scaled or corrupted accelerometer?)";
    }
    verdicts.push_back(v);
  }

  {  // Gyroscope: the wrong unit shows as a factor 180/pi (or pi/180) in the scale truth = s * gyro.
    CheckVerdict v;
    v.item = "gyro unit";
    const GyroCheck& g = check.gyro;
    const bool chose_deg = options.gyro_unit == GyroUnit::kDegPerSecond;
    const double wrong_factor = chose_deg ? 180.0 / std::numbers::pi : std::numbers::pi / 180.0;
    const GyroUnit other = chose_deg ? GyroUnit::kRadPerSecond : GyroUnit::kDegPerSecond;
    const std::string figures = "Vicon rotation = " + fixed(g.scale, 4) + " x gyro integral over " +
                                std::to_string(g.windows) + " windows (" + fixed(g.total_rotation_rad, 1) +
                                " rad), residual " + fixed(100.0 * g.relative_residual, 1) + "%";
    if (g.windows < 5 || g.total_rotation_rad < 0.5) {
      v.message = "too little rotation with ground truth to check (" + std::to_string(g.windows) + " windows, " +
                  fixed(g.total_rotation_rad, 2) + " rad)";
    } else if (near(g.scale, 1.0, 1.25) && g.relative_residual < 0.5) {
      v.status = CheckStatus::kOk;
      v.message = figures + " (--gyro-unit " + std::string(toString(options.gyro_unit)) + ")";
    } else if (near(g.scale, wrong_factor, 1.5)) {
      v.status = CheckStatus::kContradiction;
      v.message = figures + ": with --gyro-unit " + std::string(toString(options.gyro_unit)) +
                  " the gyroscope is off by a factor " + fixed(1.0 / g.scale, 4) + "; the file's unit is " +
                  std::string(toString(other)) + ": use --gyro-unit " + std::string(toString(other));
    } else {
      v.message = figures + ": gyroscope and Vicon rotation disagree for either unit (IMU axes not the Vicon body axes?)";
    }
    verdicts.push_back(v);
  }

  const TdoaCheck& t = check.tdoa;
  {  // TDoA sign: the chosen sign must fit the geometry clearly better than the opposite one.
    CheckVerdict v;
    v.item = "tdoa sign";
    const TdoaSign other = options.tdoa_sign == TdoaSign::kBMinusA ? TdoaSign::kAMinusB : TdoaSign::kBMinusA;
    const std::string figures = "median |diff - predicted| " + fixed(t.median_abs_residual_m, 3) + " m with " +
                                std::string(toString(options.tdoa_sign)) + ", " +
                                fixed(t.median_abs_residual_flipped_m, 3) + " m with " + std::string(toString(other)) +
                                " over " + std::to_string(t.samples) + " samples";
    if (t.samples < 20) {
      v.message = "too few TDoA samples with ground truth to check (" + std::to_string(t.samples) + ")";
    } else if (t.median_abs_residual_flipped_m < 0.5 * t.median_abs_residual_m) {
      v.status = CheckStatus::kContradiction;
      v.message = figures + ": the measurements have the opposite sign: use --tdoa-sign " + std::string(toString(other));
    } else if (t.median_abs_residual_m <= 0.5 * t.median_abs_residual_flipped_m) {
      if (t.median_abs_residual_m <= 0.5) {
        v.status = CheckStatus::kOk;
        v.message = figures;
      } else {
        v.message = figures + ": the sign fits better, but the residuals are large (survey of another constellation?)";
      }
    } else {
      v.message = figures + ": neither sign fits (survey of another constellation? anchor ids?)";
    }
    verdicts.push_back(v);
  }

  if (t.fit_ok && verdicts.back().status != CheckStatus::kContradiction) {
    CheckVerdict arm;
    arm.item = "lever arm";
    const Vec3& dl = t.lever_arm_correction_m;
    const Vec3& s = t.lever_arm_sigma_m;
    const std::string figures = "fitted correction (" + fixed(dl.x(), 3) + ", " + fixed(dl.y(), 3) + ", " +
                                fixed(dl.z(), 3) + ") +- (" + fixed(s.x(), 3) + ", " + fixed(s.y(), 3) + ", " +
                                fixed(s.z(), 3) + ") m over " + std::to_string(t.fit_samples) +
                                " samples, residual sigma " + fixed(t.fit_sigma_m, 3) + " m";
    if (t.lever_arm_evident) {
      const Vec3 suggested = options.lever_arm_m + dl;
      arm.message = figures + ": the antenna seems to be at (" + fixed(suggested.x(), 3) + "," +
                    fixed(suggested.y(), 3) + "," + fixed(suggested.z(), 3) + ") (--lever-arm)";
    } else {
      arm.status = CheckStatus::kOk;
      arm.message = figures + ": no evident lever-arm error";
    }
    verdicts.push_back(arm);

    CheckVerdict bias;
    bias.item = "tdoa bias";
    std::string evident;
    std::size_t count = 0;
    for (const PairBias& pb : t.pair_biases) {
      if (!pb.evident) continue;
      if (count++ > 0) evident += ", ";
      evident += pairText(pb.anchor_a, pb.anchor_b) + " " + (pb.bias_m >= 0.0 ? "+" : "") + fixed(pb.bias_m, 3) +
                 " +- " + fixed(pb.sigma_m, 3) + " m";
    }
    if (count == 0) {
      bias.status = CheckStatus::kOk;
      bias.message = "no evident constant bias in " + std::to_string(t.pair_biases.size()) + " anchor pairs";
    } else {
      bias.message = std::to_string(count) + " of " + std::to_string(t.pair_biases.size()) +
                     " anchor pairs have a constant bias (antenna delay, NLOS): " + evident;
    }
    verdicts.push_back(bias);
  }
  return verdicts;
}

bool anyContradiction(const std::vector<CheckVerdict>& verdicts) {
  return std::any_of(verdicts.begin(), verdicts.end(),
                     [](const CheckVerdict& v) { return v.status == CheckStatus::kContradiction; });
}

std::string formatUtilSummary(const UtilImport& im, const PhysicsCheck& check,
                              const std::vector<CheckVerdict>& verdicts) {
  std::string s;
  const Recording& rec = im.recording;
  s += "UTIL flight " + im.flight_file + ", anchors " + im.survey_file + "\n";
  s += "  anchors: " + std::to_string(rec.anchors.size()) + " (" + std::to_string(im.survey_orientations) +
       " orientations checked, not imported)\n";
  char line[160];
  std::snprintf(line, sizeof line, "  %-8s %9s %9s %11s %10s\n", "stream", "rows", "kept", "duplicates", "unordered");
  s += line;
  const auto row = [&](const char* name, const StreamCounts& c) {
    std::snprintf(line, sizeof line, "  %-8s %9zu %9zu %11zu %10zu", name, c.rows, c.kept, c.duplicates, c.unordered);
    s += line;
    if (c.first_duplicate_line != 0) s += "  first duplicate: line " + std::to_string(c.first_duplicate_line);
    if (c.first_unordered_line != 0) s += "  first unordered: line " + std::to_string(c.first_unordered_line);
    s += "\n";
  };
  row("tdoa", im.tdoa);
  row("accel", im.accel);
  row("gyro", im.gyro);
  row("pose", im.pose);
  const bool gyro_clock = im.options.imu_clock == ImuClock::kGyro;
  s += "  imu: " + std::to_string(rec.imu.size()) + " samples at " +
       (rec.meta.imu_rate_hz ? fixed(*rec.meta.imu_rate_hz, 1) : std::string("?")) + " Hz on the " +
       std::string(toString(im.options.imu_clock)) + " times (" + (gyro_clock ? "accelerometer" : "gyroscope") +
       " interpolated)";
  if (im.imu_without_partner > 0) {
    s += ", " + std::to_string(im.imu_without_partner) + " dropped without " +
         (gyro_clock ? "accelerometer" : "gyroscope") + " samples on both sides within " +
         fixed(im.options.max_imu_gap_s * 1e3, 0) + " ms";
  }
  s += "\n";
  if (!rec.tdoa.empty()) {
    s += "  time span: tdoa " + seconds(rec.tdoa.front().t_ns) + " .. " + seconds(rec.tdoa.back().t_ns);
    if (!rec.groundtruth.empty()) {
      s += ", ground truth " + seconds(rec.groundtruth.front().t_ns) + " .. " + seconds(rec.groundtruth.back().t_ns);
    }
    s += "\n";
  }
  if (!im.report.warnings.empty()) {
    s += "  " + std::to_string(im.report.warnings.size()) + " warning(s):\n";
    for (const ReadWarning& w : im.report.warnings) s += "    " + w.message + "\n";
  }
  s += "physics check (units and sign against the Vicon ground truth):\n";
  for (const CheckVerdict& v : verdicts) {
    std::snprintf(line, sizeof line, "  %-11s %-12s ", v.item.c_str(), std::string(toString(v.status)).c_str());
    s += line;
    s += v.message + "\n";
  }
  // Biases only mean something with the right sign (judgeUtilPhysics then gives a "tdoa bias" verdict).
  const bool sign_ok = std::any_of(verdicts.begin(), verdicts.end(),
                                   [](const CheckVerdict& v) { return v.item == "tdoa bias"; });
  if (sign_ok && check.tdoa.fit_ok && !check.tdoa.pair_biases.empty()) {
    s += "  tdoa pair biases (largest first):";
    const std::size_t n = std::min<std::size_t>(check.tdoa.pair_biases.size(), 8);
    for (std::size_t i = 0; i < n; ++i) {
      const PairBias& pb = check.tdoa.pair_biases[i];
      s += ' ';
      s += pairText(pb.anchor_a, pb.anchor_b);
      s += ' ';
      s += fixed(pb.bias_m, 3);
    }
    s += " m\n";
  }
  return s;
}

}  // namespace rilo::importer
