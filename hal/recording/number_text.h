#pragma once
// Locale-free number <-> text for the recording files, built on
// std::from_chars / std::to_chars. Parsing must consume the whole field;
// formatting gives the shortest text that parses back to the same value, so
// CSV and YAML round trips are exact.
#include <cstdint>
#include <string>
#include <string_view>

namespace rilo::recording {

enum class NumberStatus {
  kOk,
  kEmpty,        ///< field is empty
  kNotANumber,   ///< not (entirely) a number of the requested kind
  kOutOfRange,   ///< a number, but it does not fit (e.g. 1e999, t_ns beyond int64)
  kNonFinite,    ///< parsed as NaN or +-inf (doubles only)
};

NumberStatus parseDouble(std::string_view text, double& out);
NumberStatus parseInt64(std::string_view text, std::int64_t& out);
NumberStatus parseUint32(std::string_view text, std::uint32_t& out);

/// `text` in single quotes for messages: at most 40 characters (then "..."),
/// control characters shown as '?'.
std::string quoteField(std::string_view text);

/// Human-readable reason for a failed parse of `text`, e.g. "'abc' is not a number".
std::string describeNumberStatus(NumberStatus status, std::string_view text, std::string_view kind);

/// Appends the shortest round-trip representation (std::to_chars). Non-finite
/// values are appended as "nan"/"inf"/"-inf"; the writer never emits them.
void appendDouble(std::string& out, double value);
void appendInt(std::string& out, std::int64_t value);

}  // namespace rilo::recording
