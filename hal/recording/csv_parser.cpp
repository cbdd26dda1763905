#include "hal/recording/csv_parser.h"

#include <algorithm>
#include <cstring>
#include <utility>

#include "hal/recording/number_text.h"

namespace rilo::recording {
namespace {

std::string_view trim(std::string_view s) {
  std::size_t b = 0;
  std::size_t e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t')) --e;
  return s.substr(b, e - b);
}

bool contains(std::span<const std::string_view> list, std::string_view name) {
  return std::find(list.begin(), list.end(), name) != list.end();
}

}  // namespace

CsvReader::CsvReader(std::string_view text, std::string file, std::span<const std::string_view> required,
                     std::span<const std::string_view> optional, ReadReport& report)
    : text_(text), file_(std::move(file)), report_(report) {
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  if (text_.substr(0, kBom.size()) == kBom) {
    report_.warn(file_, 1, "", "UTF-8 byte order mark ignored");
    pos_ = kBom.size();
  }

  std::string_view header;
  bool unterminated = false;
  while (nextLine(header, unterminated)) {
    header = trim(header);
    if (!header.empty()) break;
    report_.warn(file_, line_no_, "", "blank line skipped");
  }
  if (header.empty()) return;  // no header: the caller decides whether that is an error
  const std::size_t header_line = line_no_;
  header_line_ = header_line;
  if (header.front() == '#') header = trim(header.substr(1));

  splitFields(header);
  names_.reserve(fields_.size());
  for (std::string_view f : fields_) names_.emplace_back(f);

  for (std::string_view req : required) {
    if (column(req) != kAbsent) continue;
    if (unterminated) {
      // A header cut short by a crash while the file was being created.
      report_.warn(file_, header_line, "", "truncated header line (no newline, column '" + std::string(req) +
                                               "' missing): file treated as empty");
      names_.clear();
      header_line_ = 0;
      return;
    }
    throw RecordingError(file_, header_line, std::string(req), "required column missing from the header");
  }
  for (std::size_t i = 0; i < names_.size(); ++i) {
    for (std::size_t j = 0; j < i; ++j) {
      if (names_[i] == names_[j] && !names_[i].empty()) {
        throw RecordingError(file_, header_line, names_[i], "column name repeated in the header");
      }
    }
    if (names_[i].empty()) {
      report_.warn(file_, header_line, "", "empty column name (field " + std::to_string(i + 1) + ") ignored");
    } else if (!contains(required, names_[i]) && !contains(optional, names_[i])) {
      report_.warn(file_, header_line, names_[i], "unknown column ignored");
    }
  }
  has_header_ = true;
}

int CsvReader::column(std::string_view name) const {
  for (std::size_t i = 0; i < names_.size(); ++i) {
    if (names_[i] == name) return static_cast<int>(i);
  }
  return kAbsent;
}

bool CsvReader::nextLine(std::string_view& line, bool& unterminated) {
  if (pos_ >= text_.size()) return false;
  const char* begin = text_.data() + pos_;
  const std::size_t remaining = text_.size() - pos_;
  const void* nl = std::memchr(begin, '\n', remaining);
  std::size_t len = 0;
  if (nl == nullptr) {
    len = remaining;
    pos_ = text_.size();
    unterminated = true;
  } else {
    len = static_cast<std::size_t>(static_cast<const char*>(nl) - begin);
    pos_ += len + 1;
    unterminated = false;
  }
  if (len > 0 && begin[len - 1] == '\r') --len;
  line = std::string_view(begin, len);
  ++line_no_;
  return true;
}

void CsvReader::splitFields(std::string_view line) {
  fields_.clear();
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      fields_.push_back(trim(line.substr(start)));
      return;
    }
    fields_.push_back(trim(line.substr(start, comma - start)));
    start = comma + 1;
  }
}

bool CsvReader::next() {
  if (!has_header_) return false;
  std::string_view line;
  bool unterminated = false;
  while (nextLine(line, unterminated)) {
    const std::string_view t = trim(line);
    if (t.empty()) {
      if (!unterminated) report_.warn(file_, line_no_, "", "blank line skipped");
      continue;
    }
    if (t.front() == '#') continue;
    row_unterminated_ = unterminated;
    splitFields(line);
    if (fields_.size() != names_.size()) {
      fail(kAbsent, "expected " + std::to_string(names_.size()) + " fields (as in the header), found " +
                        std::to_string(fields_.size()));
    }
    return true;
  }
  return false;
}

std::string_view CsvReader::field(int col) const {
  if (col == kAbsent) return {};
  return fields_[static_cast<std::size_t>(col)];
}

void CsvReader::fail(int col, const std::string& detail) const {
  throw RecordingError(file_, line_no_, col == kAbsent ? std::string() : names_[static_cast<std::size_t>(col)],
                       detail);
}

void CsvReader::warn(int col, const std::string& detail) {
  report_.warn(file_, line_no_, col == kAbsent ? std::string() : names_[static_cast<std::size_t>(col)], detail);
}

double CsvReader::requiredDouble(int col) const {
  double v = 0.0;
  const NumberStatus s = parseDouble(field(col), v);
  if (s != NumberStatus::kOk) fail(col, describeNumberStatus(s, field(col), "a number"));
  return v;
}

std::int64_t CsvReader::requiredInt64(int col) const {
  std::int64_t v = 0;
  const NumberStatus s = parseInt64(field(col), v);
  if (s != NumberStatus::kOk) fail(col, describeNumberStatus(s, field(col), "an integer"));
  return v;
}

std::uint32_t CsvReader::requiredUint32(int col) const {
  std::uint32_t v = 0;
  const NumberStatus s = parseUint32(field(col), v);
  if (s != NumberStatus::kOk) fail(col, describeNumberStatus(s, field(col), "an unsigned 32-bit integer"));
  return v;
}

std::optional<double> CsvReader::optionalDouble(int col) const {
  if (col == kAbsent || field(col).empty()) return std::nullopt;
  return requiredDouble(col);
}

std::optional<std::uint32_t> CsvReader::optionalUint32(int col) const {
  if (col == kAbsent || field(col).empty()) return std::nullopt;
  return requiredUint32(col);
}

}  // namespace rilo::recording
