#pragma once
// How the recording reader reports problems: a RecordingError (thrown, the
// recording is rejected) or a ReadWarning (the row was skipped or accepted as
// is and the reader says so). Both carry the file, the 1-based line (0 = the
// file as a whole) and the column or meta.yaml key (empty when none applies).
// The policy for which problem is which is in recording_reader.h.
#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace rilo {

/// "<file>:<line>: column '<column>': <detail>", omitting the parts that are empty/0.
/// `column_word` is "column" for CSV files and "key" for meta.yaml.
std::string formatRecordingMessage(const std::string& file, std::size_t line, const std::string& column,
                                   const std::string& detail, const char* column_word = "column");

class RecordingError : public std::runtime_error {
 public:
  RecordingError(std::string file, std::size_t line, std::string column, std::string detail,
                 const char* column_word = "column");

  const std::string& file() const { return file_; }
  std::size_t line() const { return line_; }          ///< 1-based; 0 = whole file
  const std::string& column() const { return column_; }
  const std::string& detail() const { return detail_; }

 private:
  std::string file_;
  std::size_t line_;
  std::string column_;
  std::string detail_;
};

struct ReadWarning {
  std::string file;
  std::size_t line = 0;   ///< 1-based; 0 = whole file
  std::string column;     ///< column or meta.yaml key, may be empty
  std::string message;    ///< full message, formatted like RecordingError::what()
};

/// What the reader accepted with a remark. Warnings are never dropped.
struct ReadReport {
  std::vector<ReadWarning> warnings;
  std::size_t skipped_rows = 0;  ///< data rows not in the Recording (duplicates, truncated last line)

  void warn(const std::string& file, std::size_t line, const std::string& column, const std::string& detail,
            const char* column_word = "column");
};

}  // namespace rilo
