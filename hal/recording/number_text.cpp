#include "hal/recording/number_text.h"

#include <charconv>
#include <cmath>
#include <system_error>

namespace rilo::recording {
namespace {

template <typename T>
NumberStatus parseInteger(std::string_view text, T& out) {
  if (text.empty()) return NumberStatus::kEmpty;
  T value{};
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value, 10);
  if (ec == std::errc::result_out_of_range && ptr == end) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotANumber;
  out = value;
  return NumberStatus::kOk;
}

}  // namespace

NumberStatus parseDouble(std::string_view text, double& out) {
  if (text.empty()) return NumberStatus::kEmpty;
  double value = 0.0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, value, std::chars_format::general);
  if (ec == std::errc::result_out_of_range && ptr == end) return NumberStatus::kOutOfRange;
  if (ec != std::errc() || ptr != end) return NumberStatus::kNotANumber;
  if (!std::isfinite(value)) return NumberStatus::kNonFinite;
  out = value;
  return NumberStatus::kOk;
}

NumberStatus parseInt64(std::string_view text, std::int64_t& out) { return parseInteger(text, out); }

NumberStatus parseUint32(std::string_view text, std::uint32_t& out) { return parseInteger(text, out); }

std::string quoteField(std::string_view text) {
  // Cap the echoed text: a garbage field can be megabytes long. Built by
  // appending (GCC 12 warns falsely on `"'" + std::string(...)`).
  constexpr std::size_t kMaxEcho = 40;
  std::string q;
  q.reserve(kMaxEcho + 5);
  q += '\'';
  for (char c : text.substr(0, kMaxEcho)) q += (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) ? '?' : c;
  if (text.size() > kMaxEcho) q += "...";
  q += '\'';
  return q;
}

std::string describeNumberStatus(NumberStatus status, std::string_view text, std::string_view kind) {
  const std::string quoted = quoteField(text);
  switch (status) {
    case NumberStatus::kOk: return quoted + " is fine";
    case NumberStatus::kEmpty: return "empty field, expected " + std::string(kind);
    case NumberStatus::kNotANumber: return quoted + " is not " + std::string(kind);
    case NumberStatus::kOutOfRange: return quoted + " is out of range for " + std::string(kind);
    case NumberStatus::kNonFinite: return quoted + " is not finite";
  }
  return quoted + " is invalid";
}

void appendDouble(std::string& out, double value) {
  char buf[32];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  (void)ec;  // 32 chars always suffice for a double's shortest form (at most 24)
  out.append(buf, ptr);
}

void appendInt(std::string& out, std::int64_t value) {
  char buf[24];
  const auto [ptr, ec] = std::to_chars(buf, buf + sizeof(buf), value);
  (void)ec;  // 20 digits + sign always fit
  out.append(buf, ptr);
}

}  // namespace rilo::recording
