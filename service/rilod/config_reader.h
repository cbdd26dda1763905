#pragma once
// Strict reading of YAML values for the service configuration (config.cpp):
// every value is read through a ConfigField that knows its key path and its
// line/column, so every error names the file, the key, what was expected and
// where. Mappings are opened with the complete list of keys they accept;
// anything else is an error with a "did you mean" suggestion, found before any
// value is read, so a misspelt required key reports the typo, not a missing key.
//
// Scalars are parsed from their text, not by yaml-cpp's lenient conversions:
// booleans are true/false only (not yes/no/on/off), integers are decimal or
// 0x-hex and must fit the target type, numbers must be finite unless the key
// allows .inf, and nothing may be left over ("1.5m" is not a number).
// Duplicate keys in a mapping are errors (yaml-cpp keeps the first silently).
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

#include "math/types.h"
#include "rilod/config.h"

namespace rilo::config_detail {

/// Levenshtein distance (insert, delete, substitute; case-insensitive).
std::size_t editDistance(std::string_view a, std::string_view b);
/// The candidate closest to `key` if it is plausibly a typo of it (distance at
/// most 2, or at most a third of the key's length), else empty.
std::string suggestKey(std::string_view key, const std::vector<std::string_view>& candidates);

/// What every field shares: the file name shown in messages and the directory
/// relative paths resolve against.
struct ReadContext {
  std::string file;                ///< as shown in messages
  std::filesystem::path base_dir;  ///< relative paths resolve against this
};

class ConfigMap;

class ConfigField {
 public:
  ConfigField(YAML::Node node, std::string key_path, const ReadContext* context)
      : node_(std::move(node)), path_(std::move(key_path)), context_(context) {}

  const std::string& keyPath() const { return path_; }
  const YAML::Node& node() const { return node_; }
  const ReadContext& context() const { return *context_; }
  /// Throws ConfigError at this field's position.
  [[noreturn]] void fail(const std::string& what) const;

  bool isNull() const { return node_.IsNull(); }
  /// The scalar's text; fails if the node is not a scalar.
  const std::string& scalar(std::string_view expected) const;

  bool boolean() const;
  /// Finite number in [min, max] (inf allowed only with allow_inf, and then
  /// only +inf, written .inf).
  double number(double min, double max, bool allow_inf = false) const;
  /// Number > min_exclusive, <= max.
  double positive(double max = std::numeric_limits<double>::max()) const;
  std::int64_t integer(std::int64_t min, std::int64_t max) const;
  template <typename Int>
  Int integerAs(Int min = std::numeric_limits<Int>::min(), Int max = std::numeric_limits<Int>::max()) const {
    std::int64_t hi = std::numeric_limits<std::int64_t>::max();
    if constexpr (std::is_signed_v<Int>) {
      hi = static_cast<std::int64_t>(max);
    } else {
      if (static_cast<std::uint64_t>(max) < static_cast<std::uint64_t>(hi)) hi = static_cast<std::int64_t>(max);
    }
    return static_cast<Int>(integer(static_cast<std::int64_t>(min), hi));
  }
  /// Seconds (a number) converted to integer nanoseconds, in [min_s, max_s].
  std::int64_t secondsAsNs(double min_s, double max_s) const;
  std::string string(bool allow_empty = false) const;
  /// A path; relative ones resolve against the context's base_dir. Never empty.
  std::filesystem::path path() const;
  /// One of the spellings in `choices` (exact, case-sensitive); the error lists them.
  template <typename E>
  E choice(std::initializer_list<std::pair<std::string_view, E>> choices) const {
    return choice<E>(std::span<const std::pair<std::string_view, E>>(choices.begin(), choices.size()));
  }
  /// The same from a table kept elsewhere (kSmootherMethodNames, say).
  template <typename E>
  E choice(std::span<const std::pair<std::string_view, E>> choices) const {
    const std::string& text = scalar("one of " + listChoices(choices));
    for (const auto& [name, value] : choices) {
      if (text == name) return value;
    }
    fail("expected one of " + listChoices(choices) + ", got '" + text + "'");
  }
  /// [x, y, z] of finite numbers.
  Vec3 vec3() const;
  /// The elements of a sequence, each with key path "<path>[i]". `min_size`
  /// elements at least.
  std::vector<ConfigField> sequence(std::size_t min_size = 0) const;
  /// Opens a mapping accepting exactly `keys` (see ConfigMap).
  ConfigMap map(std::initializer_list<std::string_view> keys) const;

  /// "'text'" for a scalar, "a mapping", "a sequence", "nothing (null)".
  std::string describe() const;

 private:
  template <typename E>
  static std::string listChoices(std::span<const std::pair<std::string_view, E>> choices) {
    std::string out;
    for (const auto& choice : choices) {
      if (!out.empty()) out += ", ";
      out += choice.first;
    }
    return out;
  }

  YAML::Node node_;
  std::string path_;
  const ReadContext* context_;
};

/// A mapping whose keys were all checked against the accepted list.
class ConfigMap {
 public:
  ConfigMap(const ConfigField& field, std::initializer_list<std::string_view> keys);

  bool has(std::string_view key) const { return find(key) != nullptr; }
  /// The value under `key`, if present (a present key with no value is a null field).
  std::optional<ConfigField> get(std::string_view key) const;
  /// The value under `key`; fails naming the key if it is absent.
  ConfigField require(std::string_view key) const;
  /// Reads `key` into `target` with `read(field)` if present.
  template <typename T, typename Read>
  void read(std::string_view key, T& target, Read&& read) const {
    if (auto f = get(key)) target = read(*f);
  }
  const ConfigField& self() const { return self_; }
  /// Fails at the mapping if more than one of `keys` is present.
  void exclusive(std::initializer_list<std::string_view> keys) const;

 private:
  struct Entry {
    std::string key;
    YAML::Node value;
  };
  const Entry* find(std::string_view key) const;
  std::string childPath(std::string_view key) const;

  ConfigField self_;
  std::vector<Entry> entries_;
};

/// Throws ConfigError for `path` at `mark` (mark may be null: no position).
[[noreturn]] void failAt(const ReadContext& context, const std::string& key_path, const YAML::Mark& mark,
                         const std::string& what);

}  // namespace rilo::config_detail
