#include "hal/recording/recording_writer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <span>
#include <stdexcept>
#include <system_error>

#include "hal/recording/meta_yaml.h"
#include "hal/recording/number_text.h"
#include "hal/recording/recording_files.h"

namespace rilo {
namespace {

using recording::appendDouble;
using recording::appendInt;

std::string headerLine(std::span<const std::string_view> required, std::span<const std::string_view> optional) {
  std::string h;
  for (std::string_view c : required) (h += c) += ',';
  for (std::string_view c : optional) (h += c) += ',';
  h.back() = '\n';
  return h;
}

[[noreturn]] void invalid(const std::string& what) { throw std::invalid_argument("RecordingWriter: " + what); }

void requireFinite(double v, const char* param) {
  if (!std::isfinite(v)) invalid(std::string(param) + " is not finite");
}
void requireFinite(const Vec3& v, const char* param) {
  if (!v.allFinite()) invalid(std::string(param) + " is not finite");
}
/// Optional values: NaN means unknown (empty field), infinities are invalid.
void requireFiniteOrNaN(double v, const char* param) {
  if (std::isinf(v)) invalid(std::string(param) + " is infinite (use NaN for unknown)");
}
void requireLos(int los, const char* param) {
  if (los < -1 || los > 1) invalid(std::string(param) + " = " + std::to_string(los) + " is not -1, 0 or 1");
}

void addField(std::string& line, double v) {
  line += ',';
  appendDouble(line, v);
}
void addOptionalField(std::string& line, double v) {
  line += ',';
  if (!std::isnan(v)) appendDouble(line, v);
}
void addLos(std::string& line, int los) {
  line += ',';
  if (los >= 0) line += static_cast<char>('0' + los);
}
void addVec3(std::string& line, const Vec3& v) {
  addField(line, v.x());
  addField(line, v.y());
  addField(line, v.z());
}

/// Time order of a strictly increasing stream.
void checkStrictTime(bool any, std::int64_t last, std::int64_t t, const char* what) {
  if (any && t <= last) {
    invalid(std::string(what) + ".t_ns " + std::to_string(t) + " is not after the previous " + std::to_string(last));
  }
}

/// Time order of an event stream; `keys` holds the ids used at `last`.
template <typename Key>
void checkEventTime(bool any, std::int64_t last, std::int64_t t, const std::vector<Key>& keys, const Key& key,
                    const char* what) {
  if (!any) return;
  if (t < last) {
    invalid(std::string(what) + ".t_ns " + std::to_string(t) + " is before the previous " + std::to_string(last));
  }
  if (t == last && std::find(keys.begin(), keys.end(), key) != keys.end()) {
    invalid(std::string(what) + ": a sample with the same t_ns " + std::to_string(t) + " and ids was already written");
  }
}

template <typename Key>
void commitEventKey(bool any, std::int64_t last, std::int64_t t, std::vector<Key>& keys, const Key& key) {
  if (!any || t != last) keys.clear();
  keys.push_back(key);
}

}  // namespace

RecordingWriter::RecordingWriter(std::filesystem::path dir, RecordingWriterOptions options)
    : dir_(std::move(dir)), options_(options), last_flush_(std::chrono::steady_clock::now()) {
  std::filesystem::create_directories(dir_);
  if (options_.overwrite) {
    for (std::string_view f : {recording::kMetaFile, recording::kAnchorsFile, recording::kTagsFile, recording::kImuFile,
                               recording::kRangeFile, recording::kTdoaFile, recording::kUltrasonicFile,
                               recording::kGroundTruthFile}) {
      std::filesystem::remove(dir_ / f);
    }
  }
  imu_.header = headerLine(recording::kImuRequired,
                           options_.imu_temperature ? std::span<const std::string_view>(recording::kImuOptional)
                                                    : std::span<const std::string_view>());
  range_.header = headerLine(recording::kRangeRequired, recording::kRangeOptional);
  tdoa_.header = headerLine(recording::kTdoaRequired, recording::kTdoaOptional);
  ultrasonic_.header = headerLine(recording::kUltrasonicRequired, recording::kUltrasonicOptional);
  // '#': evo's EuRoC reader takes the header line for a comment only so
  // (this reader drops the '#', csv_parser.h).
  groundtruth_.header = std::string(1, '#').append(headerLine(recording::kGroundTruthRequired, recording::kGroundTruthOptional));
  line_.reserve(512);
}

RecordingWriter::~RecordingWriter() {
  try {
    close();
  } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; close() reports errors
  }
}

void RecordingWriter::checkOpen() const {
  if (closed_) throw std::logic_error("RecordingWriter: already closed: " + dir_.string());
}

void RecordingWriter::writeMeta(const RecordingMeta& meta) {
  checkOpen();
  if (meta_written_) throw std::logic_error("RecordingWriter: meta.yaml already written");
  std::string text;
  try {
    text = recording::formatMetaYaml(meta);
  } catch (const std::invalid_argument& e) {
    invalid(e.what());
  }
  recording::writeFileAtomically(dir_ / recording::kMetaFile, text, options_.overwrite, options_.sync);
  meta_written_ = true;
  dir_dirty_ = true;
}

void RecordingWriter::writeAnchors(const std::vector<Anchor>& anchors) {
  checkOpen();
  if (anchors_written_) throw std::logic_error("RecordingWriter: anchors.csv already written");
  std::string text = headerLine(recording::kAnchorsRequired, recording::kAnchorsOptional);
  for (std::size_t i = 0; i < anchors.size(); ++i) {
    const Anchor& a = anchors[i];
    requireFinite(a.p_w_anchor, "Anchor.p_w_anchor");
    if (a.sigma_m && !(std::isfinite(*a.sigma_m) && *a.sigma_m >= 0.0)) invalid("Anchor.sigma_m must be finite and >= 0");
    for (std::size_t k = 0; k < i; ++k) {
      if (anchors[k].id == a.id) invalid("Anchor.id " + std::to_string(a.id) + " repeated");
    }
    appendInt(text, a.id);
    addVec3(text, a.p_w_anchor);
    (text += ',') += toString(a.kind);
    text += ',';
    if (a.sigma_m) appendDouble(text, *a.sigma_m);
    text += '\n';
  }
  recording::writeFileAtomically(dir_ / recording::kAnchorsFile, text, options_.overwrite, options_.sync);
  anchors_ = anchors;
  anchors_written_ = true;
  dir_dirty_ = true;
}

void RecordingWriter::writeTags(const std::vector<Tag>& tags) {
  checkOpen();
  if (tags_written_) throw std::logic_error("RecordingWriter: tags.csv already written");
  if (range_.any) throw std::logic_error("RecordingWriter: tags must be written before range samples");
  std::string text = headerLine(recording::kTagsRequired, recording::kTagsOptional);
  for (std::size_t i = 0; i < tags.size(); ++i) {
    const Tag& t = tags[i];
    requireFinite(t.p_b_tag, "Tag.p_b_tag");
    for (std::size_t k = 0; k < i; ++k) {
      if (tags[k].id == t.id) invalid("Tag.id " + std::to_string(t.id) + " repeated");
    }
    appendInt(text, t.id);
    addVec3(text, t.p_b_tag);
    text += '\n';
  }
  recording::writeFileAtomically(dir_ / recording::kTagsFile, text, options_.overwrite, options_.sync);
  tags_ = tags;
  tags_written_ = true;
  dir_dirty_ = true;
}

void RecordingWriter::ensureOpen(Stream& s, std::string_view name) {
  if (s.file.isOpen()) return;
  s.file.open(dir_ / name, options_.overwrite, std::min<std::size_t>(options_.max_buffer_bytes, 1 << 16) + 512);
  s.file.append(s.header);
  dir_dirty_ = true;
}

void RecordingWriter::emit(Stream& s, std::string_view name) {
  ensureOpen(s, name);
  s.file.append(line_);
  ++records_;
  ++records_since_flush_;
  if ((options_.flush_every_records > 0 && records_since_flush_ >= options_.flush_every_records) ||
      s.file.buffered() > options_.max_buffer_bytes) {
    flush();
  } else {
    flushIfDue();
  }
}

void RecordingWriter::write(const ImuSample& s) {
  if (options_.imu_temperature) {
    write(s, std::numeric_limits<double>::quiet_NaN());
    return;
  }
  checkOpen();
  requireFinite(s.gyro_rad_s, "ImuSample.gyro_rad_s");
  requireFinite(s.accel_m_s2, "ImuSample.accel_m_s2");
  checkStrictTime(imu_.any, imu_.last_t_ns, s.t_ns, "ImuSample");
  line_.clear();
  appendInt(line_, s.t_ns);
  addVec3(line_, s.gyro_rad_s);
  addVec3(line_, s.accel_m_s2);
  line_ += '\n';
  imu_.any = true;
  imu_.last_t_ns = s.t_ns;
  emit(imu_, recording::kImuFile);
}

void RecordingWriter::write(const ImuSample& s, double temp_c) {
  checkOpen();
  if (!options_.imu_temperature) invalid("temp_c given, but options.imu_temperature is off (imu.csv has no temp_c)");
  requireFinite(s.gyro_rad_s, "ImuSample.gyro_rad_s");
  requireFinite(s.accel_m_s2, "ImuSample.accel_m_s2");
  requireFiniteOrNaN(temp_c, "temp_c");
  checkStrictTime(imu_.any, imu_.last_t_ns, s.t_ns, "ImuSample");
  line_.clear();
  appendInt(line_, s.t_ns);
  addVec3(line_, s.gyro_rad_s);
  addVec3(line_, s.accel_m_s2);
  addOptionalField(line_, temp_c);
  line_ += '\n';
  imu_.any = true;
  imu_.last_t_ns = s.t_ns;
  emit(imu_, recording::kImuFile);
}

void RecordingWriter::write(const RangeSample& s) {
  checkOpen();
  if (!anchors_written_) throw std::logic_error("RecordingWriter: write anchors before range samples");
  requireFinite(s.range_m, "RangeSample.range_m");
  requireFiniteOrNaN(s.rssi_dbm, "RangeSample.rssi_dbm");
  requireFiniteOrNaN(s.fp_power_dbm, "RangeSample.fp_power_dbm");
  requireLos(s.los, "RangeSample.los");
  const auto anchor = std::find_if(anchors_.begin(), anchors_.end(), [&](const Anchor& a) { return a.id == s.anchor_id; });
  if (anchor == anchors_.end() || anchor->kind != AnchorKind::kUwb) {
    invalid("RangeSample.anchor_id " + std::to_string(s.anchor_id) + " is not a uwb anchor of anchors.csv");
  }
  const bool tag_known = tags_.empty() ? s.tag_id == 0
                                       : std::any_of(tags_.begin(), tags_.end(), [&](const Tag& t) { return t.id == s.tag_id; });
  if (!tag_known) invalid("RangeSample.tag_id " + std::to_string(s.tag_id) + " is not a known tag");
  const std::pair<std::uint32_t, std::uint32_t> key(s.anchor_id, s.tag_id);
  checkEventTime(range_.any, range_.last_t_ns, s.t_ns, range_keys_, key, "RangeSample");
  line_.clear();
  appendInt(line_, s.t_ns);
  line_ += ',';
  appendInt(line_, s.anchor_id);
  addField(line_, s.range_m);
  line_ += ',';
  appendInt(line_, s.tag_id);
  addOptionalField(line_, s.rssi_dbm);
  addOptionalField(line_, s.fp_power_dbm);
  addLos(line_, s.los);
  line_ += '\n';
  commitEventKey(range_.any, range_.last_t_ns, s.t_ns, range_keys_, key);
  range_.any = true;
  range_.last_t_ns = s.t_ns;
  emit(range_, recording::kRangeFile);
}

void RecordingWriter::write(const TdoaSample& s) {
  checkOpen();
  if (!anchors_written_) throw std::logic_error("RecordingWriter: write anchors before tdoa samples");
  requireFinite(s.diff_m, "TdoaSample.diff_m");
  requireFiniteOrNaN(s.rssi_a_dbm, "TdoaSample.rssi_a_dbm");
  requireFiniteOrNaN(s.fp_power_a_dbm, "TdoaSample.fp_power_a_dbm");
  requireFiniteOrNaN(s.rssi_b_dbm, "TdoaSample.rssi_b_dbm");
  requireFiniteOrNaN(s.fp_power_b_dbm, "TdoaSample.fp_power_b_dbm");
  requireLos(s.los, "TdoaSample.los");
  for (const std::uint32_t id : {s.anchor_a, s.anchor_b}) {
    const auto a = std::find_if(anchors_.begin(), anchors_.end(), [&](const Anchor& x) { return x.id == id; });
    if (a == anchors_.end() || a->kind != AnchorKind::kUwb) {
      invalid("TdoaSample anchor " + std::to_string(id) + " is not a uwb anchor of anchors.csv");
    }
  }
  if (s.anchor_a == s.anchor_b) invalid("TdoaSample.anchor_b equals anchor_a");
  const std::pair<std::uint32_t, std::uint32_t> key(s.anchor_a, s.anchor_b);
  checkEventTime(tdoa_.any, tdoa_.last_t_ns, s.t_ns, tdoa_keys_, key, "TdoaSample");
  line_.clear();
  appendInt(line_, s.t_ns);
  line_ += ',';
  appendInt(line_, s.anchor_a);
  line_ += ',';
  appendInt(line_, s.anchor_b);
  addField(line_, s.diff_m);
  addOptionalField(line_, s.rssi_a_dbm);
  addOptionalField(line_, s.fp_power_a_dbm);
  addOptionalField(line_, s.rssi_b_dbm);
  addOptionalField(line_, s.fp_power_b_dbm);
  addLos(line_, s.los);
  line_ += '\n';
  commitEventKey(tdoa_.any, tdoa_.last_t_ns, s.t_ns, tdoa_keys_, key);
  tdoa_.any = true;
  tdoa_.last_t_ns = s.t_ns;
  emit(tdoa_, recording::kTdoaFile);
}

void RecordingWriter::write(const UltrasonicSample& s) {
  checkOpen();
  if (!anchors_written_) throw std::logic_error("RecordingWriter: write anchors before ultrasonic samples");
  requireFinite(s.range_m, "UltrasonicSample.range_m");
  requireLos(s.los, "UltrasonicSample.los");
  const auto anchor = std::find_if(anchors_.begin(), anchors_.end(), [&](const Anchor& a) { return a.id == s.anchor_id; });
  if (anchor == anchors_.end() || anchor->kind != AnchorKind::kUltrasonic) {
    invalid("UltrasonicSample.anchor_id " + std::to_string(s.anchor_id) + " is not an ultrasonic anchor of anchors.csv");
  }
  checkEventTime(ultrasonic_.any, ultrasonic_.last_t_ns, s.t_ns, ultrasonic_keys_, s.anchor_id, "UltrasonicSample");
  line_.clear();
  appendInt(line_, s.t_ns);
  line_ += ',';
  appendInt(line_, s.anchor_id);
  addField(line_, s.range_m);
  addLos(line_, s.los);
  line_ += '\n';
  commitEventKey(ultrasonic_.any, ultrasonic_.last_t_ns, s.t_ns, ultrasonic_keys_, s.anchor_id);
  ultrasonic_.any = true;
  ultrasonic_.last_t_ns = s.t_ns;
  emit(ultrasonic_, recording::kUltrasonicFile);
}

void RecordingWriter::write(const GroundTruthPose& g) {
  checkOpen();
  requireFinite(g.p_w_b, "GroundTruthPose.p_w_b");
  if (!g.q_w_b.coeffs().allFinite() || !(std::abs(g.q_w_b.norm() - 1.0) <= recording::kQuaternionNormTolerance)) {
    invalid("GroundTruthPose.q_w_b is not a unit quaternion");
  }
  if (g.v_w_b) requireFinite(*g.v_w_b, "GroundTruthPose.v_w_b");
  checkStrictTime(groundtruth_.any, groundtruth_.last_t_ns, g.t_ns, "GroundTruthPose");
  line_.clear();
  appendInt(line_, g.t_ns);
  addVec3(line_, g.p_w_b);
  addField(line_, g.q_w_b.w());  // file order w, x, y, z (EuRoC)
  addField(line_, g.q_w_b.x());
  addField(line_, g.q_w_b.y());
  addField(line_, g.q_w_b.z());
  if (g.v_w_b) {
    addVec3(line_, *g.v_w_b);
  } else {
    line_ += ",,,";
  }
  line_ += '\n';
  groundtruth_.any = true;
  groundtruth_.last_t_ns = g.t_ns;
  emit(groundtruth_, recording::kGroundTruthFile);
}

void RecordingWriter::flush() {
  for (Stream* s : {&imu_, &range_, &tdoa_, &ultrasonic_, &groundtruth_}) s->file.flush(options_.sync);
  if (options_.sync && dir_dirty_) {
    recording::syncDirectory(dir_);
    dir_dirty_ = false;
  }
  records_since_flush_ = 0;
  last_flush_ = std::chrono::steady_clock::now();
}

void RecordingWriter::flushIfDue() {
  if (options_.flush_interval_ms <= 0) return;
  const auto now = std::chrono::steady_clock::now();
  if (now - last_flush_ >= std::chrono::milliseconds(options_.flush_interval_ms)) flush();
}

void RecordingWriter::close() {
  if (closed_) return;
  if (!anchors_written_) writeAnchors({});
  ensureOpen(imu_, recording::kImuFile);  // header-only imu.csv if no sample came
  closed_ = true;  // from here on, a failure is not retried by the destructor
  for (Stream* s : {&imu_, &range_, &tdoa_, &ultrasonic_, &groundtruth_}) s->file.close(options_.sync);
  if (options_.sync) recording::syncDirectory(dir_);
}

void writeRecording(const std::filesystem::path& dir, const Recording& rec, RecordingWriterOptions options) {
  const bool temps = !rec.imu_temp_c.empty();
  if (temps && rec.imu_temp_c.size() != rec.imu.size()) {
    throw std::invalid_argument("writeRecording: rec.imu_temp_c has " + std::to_string(rec.imu_temp_c.size()) +
                                " entries for " + std::to_string(rec.imu.size()) + " imu samples");
  }
  options.imu_temperature = temps;
  RecordingWriter w(dir, options);
  w.writeMeta(rec.meta);
  w.writeAnchors(rec.anchors);
  if (!rec.tags.empty()) w.writeTags(rec.tags);
  for (std::size_t i = 0; i < rec.imu.size(); ++i) {
    if (temps) {
      w.write(rec.imu[i], rec.imu_temp_c[i]);
    } else {
      w.write(rec.imu[i]);
    }
  }
  for (const RangeSample& s : rec.ranges) w.write(s);
  for (const TdoaSample& s : rec.tdoa) w.write(s);
  for (const UltrasonicSample& s : rec.ultrasonic) w.write(s);
  for (const GroundTruthPose& g : rec.groundtruth) w.write(g);
  w.close();
}

}  // namespace rilo
