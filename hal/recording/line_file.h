#pragma once
// Append-only file written in whole lines. append() only copies a complete
// line into a user-space buffer; flush() hands the buffer to the kernel with
// write() (optionally followed by fdatasync), so after any flush the file on
// disk ends at a line boundary. A process crash loses only what was appended
// since the last flush; a torn write after a power loss shows up as an
// unterminated last line, which the reader skips with a warning.
#include <filesystem>
#include <string>
#include <string_view>

namespace rilo::recording {

class LineFile {
 public:
  LineFile() = default;
  ~LineFile();  ///< closes without flushing: call close() to keep buffered lines
  LineFile(const LineFile&) = delete;
  LineFile& operator=(const LineFile&) = delete;

  /// Creates `path` for writing. Without `overwrite` an existing file is an
  /// error (std::system_error with the path and errno text, as every I/O failure).
  void open(const std::filesystem::path& path, bool overwrite, std::size_t buffer_reserve);
  bool isOpen() const { return fd_ >= 0; }
  const std::string& path() const { return path_; }

  /// `line` must be one whole line ending in '\n'.
  void append(std::string_view line) { buf_.append(line); }
  std::size_t buffered() const { return buf_.size(); }

  /// Writes every buffered line; `sync`: fdatasync afterwards.
  void flush(bool sync);
  /// flush(sync), then closes. No-op if not open.
  void close(bool sync);

 private:
  int fd_ = -1;
  std::string path_;
  std::string buf_;
};

/// Writes `text` to `path` atomically (temporary file, fsync if `sync`,
/// rename). Without `overwrite` an existing `path` is an error.
void writeFileAtomically(const std::filesystem::path& path, std::string_view text, bool overwrite, bool sync);

/// fsync of a directory, so that files created in it survive a power loss.
void syncDirectory(const std::filesystem::path& dir);

}  // namespace rilo::recording
