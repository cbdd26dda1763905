#include "hal/recording/meta_yaml.h"

#include <cmath>
#include <optional>
#include <set>
#include <stdexcept>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "hal/recording/number_text.h"

namespace rilo::recording {
namespace {

/// Constraint on a number's value; the text is used in messages.
enum class Domain { kAny, kPositive, kNonNegative };

const char* domainText(Domain d) {
  switch (d) {
    case Domain::kAny: return "any";
    case Domain::kPositive: return "> 0";
    case Domain::kNonNegative: return ">= 0";
  }
  return "?";
}

bool inDomain(double v, Domain d) {
  if (!std::isfinite(v)) return false;
  switch (d) {
    case Domain::kAny: return true;
    case Domain::kPositive: return v > 0.0;
    case Domain::kNonNegative: return v >= 0.0;
  }
  return false;
}

class MetaParser {
 public:
  MetaParser(const std::string& file, ReadReport& report) : file_(file), report_(report) {}

  RecordingMeta parse(std::string_view text) {
    YAML::Node root;
    try {
      root = YAML::Load(std::string(text));
    } catch (const YAML::Exception& e) {
      throw RecordingError(file_, lineOf(e.mark), "", "invalid YAML: " + e.msg);
    }
    RecordingMeta meta;
    if (!root.IsDefined() || root.IsNull()) return meta;  // empty file: all defaults
    if (!root.IsMap()) throw RecordingError(file_, lineOf(root.Mark()), "", "top level must be a mapping of keys");
    forEachKey(root, "", [&](const std::string& key, const std::string& path, const YAML::Node& v) {
      if (key == "name") {
        meta.name = string(path, v);
      } else if (key == "description") {
        meta.description = string(path, v);
      } else if (key == "gravity") {
        meta.gravity_m_s2 = number(path, v, Domain::kPositive);
      } else if (key == "ranging") {
        const std::string s = string(path, v);
        const std::optional<RangingKind> k = rangingKindFromString(s);
        if (!k) fail(path, v, quoteField(s) + " is not a ranging kind (ss-twr, ds-twr, tdoa)");
        meta.ranging = *k;
      } else if (key == "imu") {
        parseImu(path, v, meta);
      } else if (key == "uwb") {
        requireMap(path, v);
        forEachKey(v, path, [&](const std::string& k, const std::string& p, const YAML::Node& x) {
          if (k == "lever_arm") {
            meta.uwb_lever_arm_m = vec3(p, x);
          } else {
            unknown(k, p, x);
          }
        });
      } else if (key == "ultrasonic") {
        requireMap(path, v);
        forEachKey(v, path, [&](const std::string& k, const std::string& p, const YAML::Node& x) {
          if (k == "lever_arm") {
            meta.ultrasonic_lever_arm_m = vec3(p, x);
          } else {
            unknown(k, p, x);
          }
        });
      } else {
        unknown(key, path, v);
      }
    });
    return meta;
  }

 private:
  static std::size_t lineOf(const YAML::Mark& m) { return m.line >= 0 ? static_cast<std::size_t>(m.line) + 1 : 0; }

  [[noreturn]] void fail(const std::string& path, const YAML::Node& v, const std::string& detail) const {
    throw RecordingError(file_, lineOf(v.Mark()), path, detail, "key");
  }

  void unknown(const std::string& key, const std::string& path, const YAML::Node& v) {
    std::string detail = "unknown key ignored";
    // A flat 'imu.rate_hz: 200' instead of the nested form is a likely mistake.
    if (key.find('.') != std::string::npos) detail += " (nested keys are written as a mapping, e.g. 'imu: {rate_hz: 200}')";
    report_.warn(file_, lineOf(v.Mark()), path, detail, "key");
  }

  void requireMap(const std::string& path, const YAML::Node& v) const {
    if (!v.IsMap()) fail(path, v, "expected a mapping of keys, got " + describe(v));
  }

  template <typename Fn>
  void forEachKey(const YAML::Node& map, const std::string& prefix, Fn&& fn) {
    std::set<std::string> seen;
    for (auto it = map.begin(); it != map.end(); ++it) {
      const YAML::Node key = it->first;
      if (!key.IsScalar()) fail(prefix, key, "keys must be plain words, got " + describe(key));
      const std::string& k = key.Scalar();
      const std::string path = prefix.empty() ? k : prefix + "." + k;
      if (!seen.insert(k).second) fail(path, key, "key repeated");
      fn(k, path, it->second);
    }
  }

  void parseImu(const std::string& path, const YAML::Node& v, RecordingMeta& meta) {
    requireMap(path, v);
    forEachKey(v, path, [&](const std::string& k, const std::string& p, const YAML::Node& x) {
      if (k == "rate_hz") {
        meta.imu_rate_hz = number(p, x, Domain::kPositive);
      } else if (k == "gyro_noise_density") {
        meta.gyro_noise_density = number(p, x, Domain::kNonNegative);
      } else if (k == "accel_noise_density") {
        meta.accel_noise_density = number(p, x, Domain::kNonNegative);
      } else if (k == "gyro_bias_random_walk") {
        meta.gyro_bias_random_walk = number(p, x, Domain::kNonNegative);
      } else if (k == "accel_bias_random_walk") {
        meta.accel_bias_random_walk = number(p, x, Domain::kNonNegative);
      } else {
        unknown(k, p, x);
      }
    });
  }

  static std::string describe(const YAML::Node& v) {
    if (v.IsNull()) return "nothing";
    if (v.IsSequence()) return "a sequence";
    if (v.IsMap()) return "a mapping";
    if (v.IsScalar()) return quoteField(v.Scalar());
    return "an undefined value";
  }

  std::string string(const std::string& path, const YAML::Node& v) const {
    if (!v.IsScalar()) fail(path, v, "expected a string, got " + describe(v));
    return v.Scalar();
  }

  double number(const std::string& path, const YAML::Node& v, Domain domain) const {
    if (!v.IsScalar()) fail(path, v, "expected a number, got " + describe(v));
    double x = 0.0;
    const NumberStatus s = parseDouble(v.Scalar(), x);
    if (s != NumberStatus::kOk) fail(path, v, "expected a number: " + describeNumberStatus(s, v.Scalar(), "a number"));
    if (!inDomain(x, domain)) fail(path, v, "value " + v.Scalar() + " must be " + domainText(domain));
    return x;
  }

  Vec3 vec3(const std::string& path, const YAML::Node& v) const {
    if (!v.IsSequence() || v.size() != 3) fail(path, v, "expected [x, y, z], got " + describe(v));
    Vec3 out;
    for (std::size_t i = 0; i < 3; ++i) out[static_cast<Eigen::Index>(i)] = number(path, v[i], Domain::kAny);
    return out;
  }

  const std::string& file_;
  ReadReport& report_;
};

std::string numberText(double v, const char* field, Domain domain) {
  if (!inDomain(v, domain)) {
    throw std::invalid_argument(std::string("meta.") + field + ": value must be finite and " + domainText(domain));
  }
  std::string s;
  appendDouble(s, v);
  return s;
}

void emitVec3(YAML::Emitter& out, const Vec3& v, const char* field) {
  out << YAML::Flow << YAML::BeginSeq;
  for (int i = 0; i < 3; ++i) out << numberText(v[i], field, Domain::kAny);
  out << YAML::EndSeq;
}

}  // namespace

RecordingMeta parseMetaYaml(std::string_view text, const std::string& file, ReadReport& report) {
  try {
    return MetaParser(file, report).parse(text);
  } catch (const YAML::Exception& e) {
    // Node access on odd documents (aliases, complex keys) can throw too.
    throw RecordingError(file, e.mark.line >= 0 ? static_cast<std::size_t>(e.mark.line) + 1 : 0, "",
                         "invalid YAML: " + e.msg);
  }
}

std::string formatMetaYaml(const RecordingMeta& meta) {
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << meta.name;
  out << YAML::Key << "description" << YAML::Value << YAML::DoubleQuoted << meta.description;
  out << YAML::Key << "gravity" << YAML::Value << numberText(meta.gravity_m_s2, "gravity_m_s2", Domain::kPositive);
  const std::pair<const char*, const std::optional<double>*> imu_fields[] = {
      {"rate_hz", &meta.imu_rate_hz},
      {"gyro_noise_density", &meta.gyro_noise_density},
      {"accel_noise_density", &meta.accel_noise_density},
      {"gyro_bias_random_walk", &meta.gyro_bias_random_walk},
      {"accel_bias_random_walk", &meta.accel_bias_random_walk},
  };
  bool any_imu = false;
  for (const auto& [key, value] : imu_fields) any_imu = any_imu || value->has_value();
  if (any_imu) {
    out << YAML::Key << "imu" << YAML::Value << YAML::BeginMap;
    for (const auto& [key, value] : imu_fields) {
      if (!value->has_value()) continue;
      const Domain d = std::string_view(key) == "rate_hz" ? Domain::kPositive : Domain::kNonNegative;
      out << YAML::Key << key << YAML::Value << numberText(**value, key, d);
    }
    out << YAML::EndMap;
  }
  if (meta.uwb_lever_arm_m) {
    out << YAML::Key << "uwb" << YAML::Value << YAML::BeginMap << YAML::Key << "lever_arm" << YAML::Value;
    emitVec3(out, *meta.uwb_lever_arm_m, "uwb_lever_arm_m");
    out << YAML::EndMap;
  }
  if (meta.ultrasonic_lever_arm_m) {
    out << YAML::Key << "ultrasonic" << YAML::Value << YAML::BeginMap << YAML::Key << "lever_arm" << YAML::Value;
    emitVec3(out, *meta.ultrasonic_lever_arm_m, "ultrasonic_lever_arm_m");
    out << YAML::EndMap;
  }
  if (meta.ranging) out << YAML::Key << "ranging" << YAML::Value << std::string(toString(*meta.ranging));
  out << YAML::EndMap;
  if (!out.good()) throw std::invalid_argument("meta: cannot emit YAML: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

}  // namespace rilo::recording
