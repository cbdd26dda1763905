#pragma once
// Streaming writer of a recording folder (recording-format.md).
//
// Samples are written as they arrive: each stream's CSV (imu, range, tdoa,
// ultrasonic, groundtruth) is created on its first sample, header first.
// Every sample is formatted as one whole line into the stream's buffer, and
// buffers go to the kernel on flush(): automatically every
// `flush_every_records` records or `flush_interval_ms` (checked on each
// write), or when a buffer grows past `max_buffer_bytes`. So the files on disk
// are always a valid prefix of whole lines and a crash loses at most the last
// flush interval (with `sync`, a power loss too: fdatasync per flush).
// anchors.csv, tags.csv and meta.yaml are small and written at once,
// atomically (temporary file + rename).
//
// The writer refuses (std::invalid_argument naming the parameter) what the
// reader would reject or warn about, so whatever it writes reads back
// identically: non-finite required values (an optional value may be NaN:
// written as an empty field), los not in {-1, 0, 1}, time going backwards
// (imu and groundtruth must strictly increase; range, tdoa, ultrasonic rows
// may share a t_ns but not the same ids), anchors or tags it does not know,
// repeated ids, a ground-truth quaternion that is not unit. Anchors (and
// tags, if any) must be written before the samples that refer to them
// (std::logic_error otherwise).
//
// Numbers are written with std::to_chars (shortest text that reads back to
// the same double). After warm-up, writing a sample does not allocate.
// Not thread-safe: one writer per thread, or external locking.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "hal/recording/line_file.h"
#include "hal/recording/recording.h"

namespace rilo {

struct RecordingWriterOptions {
  std::size_t flush_every_records = 1000;  ///< flush after this many records (all streams); 0 = no count trigger
  std::int64_t flush_interval_ms = 200;    ///< flush when this long since the last flush; <= 0 = no time trigger
  std::size_t max_buffer_bytes = 1 << 20;  ///< flush when one stream's buffer exceeds this (bounds memory)
  bool sync = false;                       ///< fdatasync after each flush (survive power loss, costs ms)
  bool imu_temperature = false;            ///< imu.csv gets a temp_c column
  bool overwrite = false;                  ///< replace a recording in dir (its files are deleted first) instead of refusing
};

class RecordingWriter {
 public:
  /// Creates `dir` (and parents) if needed. No file is created yet; with
  /// options.overwrite, the recording files already in `dir` are deleted so
  /// none of them outlives the new recording.
  explicit RecordingWriter(std::filesystem::path dir, RecordingWriterOptions options = {});
  /// Calls close(); errors are swallowed there, so call close() yourself.
  ~RecordingWriter();
  RecordingWriter(const RecordingWriter&) = delete;
  RecordingWriter& operator=(const RecordingWriter&) = delete;

  // Static files, each written once, atomically.
  void writeMeta(const RecordingMeta& meta);
  void writeAnchors(const std::vector<Anchor>& anchors);
  void writeTags(const std::vector<Tag>& tags);

  // Streams.
  void write(const ImuSample& s);
  void write(const ImuSample& s, double temp_c);  ///< needs options.imu_temperature; NaN = unknown
  void write(const RangeSample& s);
  void write(const TdoaSample& s);
  void write(const UltrasonicSample& s);
  void write(const GroundTruthPose& g);

  /// Hands every buffered line to the kernel (and fdatasync with options.sync).
  void flush();
  /// Flushes if the time trigger is due; for callers whose streams go quiet.
  void flushIfDue();
  /// Flushes, closes every file, and creates anchors.csv and imu.csv
  /// (header only) if they were never written, so the folder reads back.
  void close();

  std::size_t recordsWritten() const { return records_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  struct Stream {
    recording::LineFile file;
    std::string header;
    std::int64_t last_t_ns = 0;
    bool any = false;
  };

  void ensureOpen(Stream& s, std::string_view name);
  void emit(Stream& s, std::string_view name);  ///< appends line_ to s, counts, maybe flushes
  void checkOpen() const;

  std::filesystem::path dir_;
  RecordingWriterOptions options_;
  bool closed_ = false;
  bool dir_dirty_ = false;  ///< a file was created since the last directory fsync

  Stream imu_, range_, tdoa_, ultrasonic_, groundtruth_;
  std::string line_;  ///< scratch line, reused

  bool meta_written_ = false;
  bool anchors_written_ = false;
  bool tags_written_ = false;
  std::vector<Anchor> anchors_;
  std::vector<Tag> tags_;

  // Ids already used at the current t_ns of each event stream.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> range_keys_, tdoa_keys_;
  std::vector<std::uint32_t> ultrasonic_keys_;

  std::size_t records_ = 0;
  std::size_t records_since_flush_ = 0;
  std::chrono::steady_clock::time_point last_flush_;
};

/// Writes all of `rec` into `dir` (imu.csv gets temp_c if rec.imu_temp_c is
/// non-empty, which must then match rec.imu in size). `options.imu_temperature`
/// is set from the recording.
void writeRecording(const std::filesystem::path& dir, const Recording& rec, RecordingWriterOptions options = {});

}  // namespace rilo
