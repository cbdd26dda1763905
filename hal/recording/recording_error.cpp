#include "hal/recording/recording_error.h"

#include <utility>

namespace rilo {

std::string formatRecordingMessage(const std::string& file, std::size_t line, const std::string& column,
                                   const std::string& detail, const char* column_word) {
  // Appends only: GCC 12 gives a false -Wrestrict on `":" + std::to_string(...)`.
  std::string msg = file;
  if (line > 0) {
    msg += ':';
    msg += std::to_string(line);
  }
  msg += ": ";
  if (!column.empty()) {
    msg += column_word;
    msg += " '";
    msg += column;
    msg += "': ";
  }
  msg += detail;
  return msg;
}

RecordingError::RecordingError(std::string file, std::size_t line, std::string column, std::string detail,
                               const char* column_word)
    : std::runtime_error(formatRecordingMessage(file, line, column, detail, column_word)),
      file_(std::move(file)),
      line_(line),
      column_(std::move(column)),
      detail_(std::move(detail)) {}

void ReadReport::warn(const std::string& file, std::size_t line, const std::string& column,
                      const std::string& detail, const char* column_word) {
  warnings.push_back(ReadWarning{file, line, column, formatRecordingMessage(file, line, column, detail, column_word)});
}

}  // namespace rilo
