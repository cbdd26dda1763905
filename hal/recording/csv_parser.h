#pragma once
// Line-by-line reader for the recording CSV files (no quoting: every field is
// a number or a bare word). It finds the header, maps column names to
// indices, splits rows into fields and parses them with from_chars; every
// failure is a RecordingError naming the file, the 1-based line and the
// column. It applies no policy about time order or references: that is the
// job of the per-file readers in recording_reader.cpp.
//
// Lexical rules (recording-format.md):
//  - the first non-blank line is the header; a leading '#' on it is dropped;
//  - later lines whose first non-blank character is '#' are comments;
//  - "\r\n" line endings are accepted; spaces and tabs around a field are
//    ignored; a UTF-8 byte order mark at the start is ignored with a warning;
//  - blank lines are skipped with a warning;
//  - unknown header columns are ignored with a warning, repeated column
//    names are an error, a missing required column is an error;
//  - a header that is the unterminated last line and lacks a required column
//    is taken as cut short by a crash: warning, and the file has no header.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "hal/recording/recording_error.h"

namespace rilo::recording {

class CsvReader {
 public:
  static constexpr int kAbsent = -1;

  /// Parses the header of `text` (the whole file). `file` is used in messages.
  /// Throws RecordingError on a bad header (see the rules above).
  CsvReader(std::string_view text, std::string file, std::span<const std::string_view> required,
            std::span<const std::string_view> optional, ReadReport& report);

  /// False when the file has no header line (empty, or only blank lines).
  bool hasHeader() const { return has_header_; }
  /// Index of the column in each row, or kAbsent if the header lacks it.
  int column(std::string_view name) const;

  /// Advances to the next data row (skipping comments and blank lines).
  /// Returns false at the end of the file. Throws RecordingError if the row's
  /// field count differs from the header's.
  bool next();

  std::size_t line() const { return line_no_; }          ///< 1-based line of the current row
  std::size_t headerLine() const { return header_line_; }  ///< 1-based line of the header (0 if none)
  /// True if the current row is the file's last line and has no '\n'.
  bool rowUnterminated() const { return row_unterminated_; }
  const std::string& file() const { return file_; }
  ReadReport& report() { return report_; }

  /// Raw (trimmed) field; an absent column gives "".
  std::string_view field(int col) const;

  // Typed access to the current row. Required: the field must hold a finite
  // number of the kind. Optional: an absent column or an empty field gives
  // nullopt; anything else must parse.
  double requiredDouble(int col) const;
  std::int64_t requiredInt64(int col) const;
  std::uint32_t requiredUint32(int col) const;
  std::optional<double> optionalDouble(int col) const;
  std::optional<std::uint32_t> optionalUint32(int col) const;

  /// Throws RecordingError for the current row; `col` may be kAbsent (no column).
  [[noreturn]] void fail(int col, const std::string& detail) const;
  /// Records a warning for the current row.
  void warn(int col, const std::string& detail);

 private:
  /// Next physical line into `line`; false at the end. Sets line_no_ and unterminated.
  bool nextLine(std::string_view& line, bool& unterminated);
  void splitFields(std::string_view line);

  std::string_view text_;
  std::size_t pos_ = 0;
  std::string file_;
  ReadReport& report_;
  bool has_header_ = false;
  std::vector<std::string> names_;          ///< header names, in file order
  std::vector<std::string_view> fields_;    ///< fields of the current row (views into text_)
  std::size_t line_no_ = 0;
  std::size_t header_line_ = 0;
  bool row_unterminated_ = false;
};

}  // namespace rilo::recording
