#include "evaluation/tum.h"

#include <array>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <system_error>

#include "hal/recording/number_text.h"

namespace rilo {

namespace {

constexpr std::size_t kFields = 8;
constexpr std::array<std::string_view, kFields> kFieldNames = {"t", "x", "y", "z", "qx", "qy", "qz", "qw"};

std::string tumMessage(const std::string& file, std::size_t line, std::size_t field, const std::string& detail) {
  // Built by appending (GCC 12 warns falsely on `":" + std::string(...)`).
  std::string m = file;
  if (line > 0) {
    m += ':';
    m += std::to_string(line);
  }
  m += ": ";
  if (field > 0) {
    m += "field ";
    m += std::to_string(field);
    m += " (";
    m += tumFieldName(field);
    m += "): ";
  }
  m += detail;
  return m;
}

/// t_ns from the text of a time field that already parsed as the finite
/// double `seconds`. Plain decimals are converted digit by digit (no double
/// rounding at 1e9 s and beyond); false if the time does not fit int64 ns.
bool timeNsFromText(std::string_view text, double seconds, std::int64_t& t_ns) {
  if (text.find_first_of("eE") != std::string_view::npos) {
    const double ns = seconds * 1e9;
    if (!(std::abs(ns) < 9.2e18)) return false;
    t_ns = std::llround(ns);
    return true;
  }
  const bool negative = !text.empty() && text.front() == '-';
  if (negative) text.remove_prefix(1);
  const std::size_t dot = text.find('.');
  const std::string_view whole = text.substr(0, dot);
  const std::string_view frac = dot == std::string_view::npos ? std::string_view() : text.substr(dot + 1);
  std::int64_t ns = 0;
  for (char c : whole) {
    if (__builtin_mul_overflow(ns, std::int64_t{10}, &ns) || __builtin_add_overflow(ns, std::int64_t{c - '0'}, &ns)) {
      return false;
    }
  }
  if (__builtin_mul_overflow(ns, std::int64_t{1'000'000'000}, &ns)) return false;
  std::int64_t frac_ns = 0;
  for (std::size_t k = 0; k < 9; ++k) frac_ns = frac_ns * 10 + (k < frac.size() ? frac[k] - '0' : 0);
  if (frac.size() > 9 && frac[9] >= '5') ++frac_ns;  // round half away from zero
  if (__builtin_add_overflow(ns, frac_ns, &ns)) return false;
  t_ns = negative ? -ns : ns;
  return true;
}


}  // namespace

std::string secondsText(std::int64_t t_ns) {
  // Exact "%.9f" of t_ns * 1e-9, without going through double.
  const bool negative = t_ns < 0;
  const std::uint64_t mag = negative ? static_cast<std::uint64_t>(-(t_ns + 1)) + 1u : static_cast<std::uint64_t>(t_ns);
  char buf[48];
  std::snprintf(buf, sizeof buf, "%s%" PRIu64 ".%09" PRIu64, negative ? "-" : "", mag / 1'000'000'000u,
                mag % 1'000'000'000u);
  return buf;
}


TumError::TumError(std::string file, std::size_t line, std::size_t field, const std::string& detail)
    : std::runtime_error(tumMessage(file, line, field, detail)), file_(std::move(file)), line_(line), field_(field) {}

std::string_view tumFieldName(std::size_t field) {
  return field >= 1 && field <= kFields ? kFieldNames[field - 1] : std::string_view("?");
}

TumTrajectory parseTum(std::string_view text, const std::string& file) {
  TumTrajectory poses;
  std::size_t line_no = 0;
  std::size_t previous_line = 0;
  std::array<std::string_view, kFields> fields;
  std::array<double, kFields> values{};
  while (!text.empty()) {
    ++line_no;
    const std::size_t eol = text.find('\n');
    std::string_view line = text.substr(0, eol);
    text.remove_prefix(eol == std::string_view::npos ? text.size() : eol + 1);
    if (const std::size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);

    std::size_t count = 0;
    std::size_t pos = 0;
    while (true) {
      pos = line.find_first_not_of(" \t", pos);
      if (pos == std::string_view::npos) break;
      const std::size_t end = std::min(line.find_first_of(" \t", pos), line.size());
      if (count < kFields) fields[count] = line.substr(pos, end - pos);
      ++count;
      pos = end;
    }
    if (count == 0) continue;  // blank or comment-only line
    if (count != kFields) {
      throw TumError(file, line_no, 0,
                     "expected 8 fields (t x y z qx qy qz qw), found " + std::to_string(count));
    }
    for (std::size_t k = 0; k < kFields; ++k) {
      const recording::NumberStatus status = recording::parseDouble(fields[k], values[k]);
      if (status != recording::NumberStatus::kOk) {
        throw TumError(file, line_no, k + 1, recording::describeNumberStatus(status, fields[k], "a number"));
      }
    }
    std::int64_t t_ns = 0;
    if (!timeNsFromText(fields[0], values[0], t_ns)) {
      throw TumError(file, line_no, 1, recording::quoteField(fields[0]) + " s is out of range for int64 nanoseconds");
    }
    if (!poses.empty() && t_ns <= poses.back().t_ns) {
      throw TumError(file, line_no, 1,
                     "time " + secondsText(t_ns) + " s is not after the previous pose's " +
                         secondsText(poses.back().t_ns) + " s (line " + std::to_string(previous_line) +
                         "): times must strictly increase");
    }
    const Quat q(values[7], values[4], values[5], values[6]);  // Eigen: w first
    const double norm = q.norm();
    if (!(std::abs(norm - 1.0) <= kTumQuaternionTolerance)) {
      char detail[160];
      std::snprintf(detail, sizeof detail,
                    "quaternion (qx qy qz qw, fields 5-8) has norm %.6g, which differs from 1 by more than %g", norm,
                    kTumQuaternionTolerance);
      throw TumError(file, line_no, 5, detail);
    }
    poses.push_back({t_ns, Pose3(q, Vec3(values[1], values[2], values[3]))});
    previous_line = line_no;
  }
  return poses;
}

TumTrajectory readTum(const std::filesystem::path& file) {
  std::error_code ec;
  if (std::filesystem::is_directory(file, ec)) throw TumError(file.string(), 0, 0, "is a folder, expected a TUM file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw TumError(file.string(), 0, 0, "cannot open the file for reading");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw TumError(file.string(), 0, 0, "read error");
  return parseTum(text.str(), file.string());
}

std::string formatTum(const TumTrajectory& poses) {
  std::string out = "# t_s x y z qx qy qz qw (TUM; world frame of the anchors)\n";
  out.reserve(out.size() + poses.size() * 96);
  std::string line(256, '\0');
  for (const auto& p : poses) {
    const Eigen::Quaterniond q(p.T_w_b.R);
    const auto print = [&] {
      return std::snprintf(line.data(), line.size(), " %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", p.T_w_b.p.x(),
                           p.T_w_b.p.y(), p.T_w_b.p.z(), q.x(), q.y(), q.z(), q.w());
    };
    int n = print();
    if (n >= 0 && static_cast<std::size_t>(n) >= line.size()) {  // huge coordinates: never truncate a line
      line.resize(static_cast<std::size_t>(n) + 1);
      n = print();
    }
    out += secondsText(p.t_ns);
    out.append(line.data(), n > 0 ? static_cast<std::size_t>(n) : 0u);
  }
  return out;
}

void writeTum(const std::filesystem::path& file, const TumTrajectory& poses) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out << formatTum(poses);
  out.flush();
  if (!out) throw std::runtime_error("cannot write " + file.string());
}

}  // namespace rilo
