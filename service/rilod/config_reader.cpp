#include "rilod/config_reader.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <system_error>

namespace rilo {

namespace {

std::string formatError(const std::string& file, const std::string& key_path, int line, int column,
                        const std::string& detail) {
  std::string out = file;
  if (line > 0) {
    out += ':' + std::to_string(line);
    if (column > 0) out += ':' + std::to_string(column);
  }
  out += ": " + key_path + ": " + detail;
  return out;
}

}  // namespace

ConfigError::ConfigError(std::string file, std::string key_path, int line, int column, std::string detail)
    : std::invalid_argument(formatError(file, key_path.empty() ? "(top level)" : key_path, line, column, detail)),
      file_(std::move(file)),
      key_path_(key_path.empty() ? "(top level)" : std::move(key_path)),
      line_(line),
      column_(column),
      detail_(std::move(detail)) {}

namespace config_detail {

namespace {

char lower(char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); }

std::string shortText(const std::string& text) {
  constexpr std::size_t kMax = 60;
  if (text.size() <= kMax) return text;
  return text.substr(0, kMax) + "...";
}

std::string formatNumber(double x) {
  if (x == std::numeric_limits<double>::max()) return "max";
  if (x == -std::numeric_limits<double>::max()) return "-max";
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof(buf), x);
  return std::string(buf, res.ptr);
}

/// 'text' (appending, see interval()).
std::string quote(const std::string& text) {
  std::string out;
  out.reserve(text.size() + 2);
  out += '\'';
  out += text;
  out += '\'';
  return out;
}

/// "[lo, hi]". Built by appending: GCC 12 reports a false -Wrestrict on
/// "[" + a + ", " + b + "]" chains at -O3.
std::string interval(const std::string& lo, const std::string& hi) {
  std::string out;
  out.reserve(lo.size() + hi.size() + 4);
  out += '[';
  out += lo;
  out += ", ";
  out += hi;
  out += ']';
  return out;
}

/// Parses YAML's spellings of +-infinity; nullopt if the text is not one.
std::optional<double> parseInfinity(std::string_view text) {
  bool negative = false;
  if (!text.empty() && (text.front() == '+' || text.front() == '-')) {
    negative = text.front() == '-';
    text.remove_prefix(1);
  }
  if (text == ".inf" || text == ".Inf" || text == ".INF" || text == "inf" || text == "infinity") {
    return negative ? -std::numeric_limits<double>::infinity() : std::numeric_limits<double>::infinity();
  }
  return std::nullopt;
}

}  // namespace

std::size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t substitute = prev[j - 1] + (lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, substitute});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

std::string suggestKey(std::string_view key, const std::vector<std::string_view>& candidates) {
  std::string_view best;
  std::size_t best_distance = std::numeric_limits<std::size_t>::max();
  for (std::string_view c : candidates) {
    const std::size_t d = editDistance(key, c);
    if (d < best_distance) {
      best_distance = d;
      best = c;
    }
  }
  if (best.empty()) return {};
  const bool plausible = best_distance <= 2 ? best_distance < std::max(key.size(), best.size())
                                            : 3 * best_distance <= key.size();
  return plausible ? std::string(best) : std::string();
}

void failAt(const ReadContext& context, const std::string& key_path, const YAML::Mark& mark,
            const std::string& what) {
  const bool known = !mark.is_null() && mark.line >= 0;
  throw ConfigError(context.file, key_path, known ? mark.line + 1 : 0, known ? mark.column + 1 : 0, what);
}

// --- ConfigField --------------------------------------------------------------

void ConfigField::fail(const std::string& what) const { failAt(*context_, path_, node_.Mark(), what); }

std::string ConfigField::describe() const {
  switch (node_.Type()) {
    case YAML::NodeType::Scalar: return quote(shortText(node_.Scalar()));
    case YAML::NodeType::Map: return "a mapping";
    case YAML::NodeType::Sequence: return "a sequence";
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined: break;
  }
  return "nothing (null)";
}

const std::string& ConfigField::scalar(std::string_view expected) const {
  if (!node_.IsScalar()) fail("expected " + std::string(expected) + ", got " + describe());
  return node_.Scalar();
}

bool ConfigField::boolean() const {
  const std::string& text = scalar("true or false");
  if (text == "true" || text == "True" || text == "TRUE") return true;
  if (text == "false" || text == "False" || text == "FALSE") return false;
  fail("expected true or false, got '" + shortText(text) + "'");
}

double ConfigField::number(double min, double max, bool allow_inf) const {
  const std::string range = interval(formatNumber(min), allow_inf ? std::string(".inf") : formatNumber(max));
  const std::string& text = scalar("a number in " + range);
  double value = 0.0;
  if (auto inf = parseInfinity(text)) {
    if (!allow_inf || *inf < 0.0) fail("expected a finite number in " + range + ", got '" + shortText(text) + "'");
    return *inf;
  }
  std::string_view view = text;
  if (!view.empty() && view.front() == '+') view.remove_prefix(1);
  const auto [ptr, ec] = std::from_chars(view.data(), view.data() + view.size(), value);
  if (view.empty() || ec == std::errc::invalid_argument || ptr != view.data() + view.size()) {
    fail("expected a number in " + range + ", got '" + shortText(text) + "'");
  }
  if (ec == std::errc::result_out_of_range || !std::isfinite(value)) {
    fail("expected a finite number in " + range + ", got '" + shortText(text) + "'");
  }
  if (value < min || value > max) fail("expected a number in " + range + ", got " + shortText(text));
  return value;
}

double ConfigField::positive(double max) const {
  const double value = number(0.0, max);
  if (!(value > 0.0)) fail("expected a number > 0, got " + node_.Scalar());
  return value;
}

std::int64_t ConfigField::integer(std::int64_t min, std::int64_t max) const {
  const std::string range = interval(std::to_string(min), std::to_string(max));
  const std::string& text = scalar("an integer in " + range);
  std::string_view view = text;
  bool negative = false;
  if (!view.empty() && (view.front() == '+' || view.front() == '-')) {
    negative = view.front() == '-';
    view.remove_prefix(1);
  }
  int base = 10;
  if (view.size() > 2 && view[0] == '0' && (view[1] == 'x' || view[1] == 'X')) {
    base = 16;
    view.remove_prefix(2);
  }
  std::uint64_t magnitude = 0;
  const auto [ptr, ec] = std::from_chars(view.data(), view.data() + view.size(), magnitude, base);
  if (view.empty() || ec == std::errc::invalid_argument || ptr != view.data() + view.size()) {
    fail("expected an integer in " + range + ", got '" + shortText(text) + "'");
  }
  constexpr auto kMaxMagnitude = static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
  if (ec == std::errc::result_out_of_range || magnitude > kMaxMagnitude + (negative ? 1u : 0u)) {
    fail("expected an integer in " + range + ", got " + shortText(text));
  }
  std::int64_t value = 0;
  if (negative) {
    value = magnitude == kMaxMagnitude + 1u ? std::numeric_limits<std::int64_t>::min()
                                            : -static_cast<std::int64_t>(magnitude);
  } else {
    value = static_cast<std::int64_t>(magnitude);
  }
  if (value < min || value > max) fail("expected an integer in " + range + ", got " + shortText(text));
  return value;
}

std::int64_t ConfigField::secondsAsNs(double min_s, double max_s) const {
  const double seconds = number(min_s, max_s);
  return static_cast<std::int64_t>(std::llround(seconds * 1e9));
}

std::string ConfigField::string(bool allow_empty) const {
  const std::string& text = scalar("a string");
  if (!allow_empty && text.empty()) fail("expected a non-empty string");
  return text;
}

std::filesystem::path ConfigField::path() const {
  const std::string text = string();
  std::filesystem::path p(text);
  if (p.is_relative()) p = context_->base_dir / p;
  return p.lexically_normal();
}

Vec3 ConfigField::vec3() const {
  if (!node_.IsSequence() || node_.size() != 3) fail("expected [x, y, z] (3 numbers), got " + describe());
  Vec3 v;
  for (std::size_t i = 0; i < 3; ++i) {
    v[static_cast<Eigen::Index>(i)] =
        ConfigField(node_[i], path_ + "[" + std::to_string(i) + "]", context_)
            .number(-std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  }
  return v;
}

std::vector<ConfigField> ConfigField::sequence(std::size_t min_size) const {
  if (!node_.IsSequence()) {
    fail("expected a sequence" + (min_size > 0 ? " of at least " + std::to_string(min_size) + " items" : "") +
         ", got " + describe());
  }
  if (node_.size() < min_size) {
    fail("expected at least " + std::to_string(min_size) + " items, got " + std::to_string(node_.size()));
  }
  std::vector<ConfigField> items;
  items.reserve(node_.size());
  for (std::size_t i = 0; i < node_.size(); ++i) {
    items.emplace_back(node_[i], path_ + "[" + std::to_string(i) + "]", context_);
  }
  return items;
}

ConfigMap ConfigField::map(std::initializer_list<std::string_view> keys) const { return ConfigMap(*this, keys); }

// --- ConfigMap ----------------------------------------------------------------

ConfigMap::ConfigMap(const ConfigField& field, std::initializer_list<std::string_view> keys) : self_(field) {
  const YAML::Node& node = field.node();
  if (!node.IsMap()) field.fail("expected a mapping (key: value lines), got " + field.describe());
  const std::vector<std::string_view> accepted(keys);
  for (auto it = node.begin(); it != node.end(); ++it) {
    const YAML::Node key = it->first;
    const ConfigField key_field(key, field.keyPath(), &field.context());
    if (!key.IsScalar()) key_field.fail("expected a plain key, got " + key_field.describe());
    const std::string& name = key.Scalar();
    if (std::find(accepted.begin(), accepted.end(), name) == accepted.end()) {
      std::string what = "unknown key '" + shortText(name) + "'";
      const std::string suggestion = suggestKey(name, accepted);
      if (!suggestion.empty()) {
        what += ": did you mean '" + suggestion + "'?";
      } else {
        what += " (accepted: ";
        for (std::size_t i = 0; i < accepted.size(); ++i) what += (i ? ", " : "") + std::string(accepted[i]);
        what += ")";
      }
      failAt(field.context(), field.keyPath(), key.Mark(), what);
    }
    if (find(name) != nullptr) {
      failAt(field.context(), childPath(name), key.Mark(), "duplicate key '" + name + "' (given twice in this mapping)");
    }
    entries_.push_back({name, it->second});
  }
}

const ConfigMap::Entry* ConfigMap::find(std::string_view key) const {
  for (const Entry& e : entries_) {
    if (e.key == key) return &e;
  }
  return nullptr;
}

std::string ConfigMap::childPath(std::string_view key) const {
  return self_.keyPath().empty() ? std::string(key) : self_.keyPath() + "." + std::string(key);
}

std::optional<ConfigField> ConfigMap::get(std::string_view key) const {
  const Entry* e = find(key);
  if (e == nullptr) return std::nullopt;
  return ConfigField(e->value, childPath(key), &self_.context());
}

ConfigField ConfigMap::require(std::string_view key) const {
  if (auto f = get(key)) return *f;
  failAt(self_.context(), childPath(key), self_.node().Mark(),
         "required key '" + std::string(key) + "' is missing" +
             (self_.keyPath().empty() ? std::string() : " in " + self_.keyPath()));
}

void ConfigMap::exclusive(std::initializer_list<std::string_view> keys) const {
  std::vector<std::string_view> present;
  for (std::string_view k : keys) {
    if (has(k)) present.push_back(k);
  }
  if (present.size() > 1) {
    self_.fail("give only one of '" + std::string(present[0]) + "' and '" + std::string(present[1]) + "'");
  }
}

}  // namespace config_detail
}  // namespace rilo
