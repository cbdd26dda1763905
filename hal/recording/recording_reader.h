#pragma once
// Strict reader of a recording folder (recording-format.md).
//
// Policy. The reader never fixes data silently and never crashes on bad
// input: a problem either rejects the recording (RecordingError, message
// "<file>:<line>: column '<name>': <what>") or is a counted warning in the
// ReadReport when a real recording may legitimately contain it and skipping
// or keeping the row is safe.
//
// Errors (RecordingError):
//  - the folder, anchors.csv or imu.csv is missing or unreadable; anchors.csv
//    or imu.csv is empty (no header line);
//  - a header lacks a required column or repeats a column name; groundtruth.csv
//    has only some of vx,vy,vz;
//  - a row (other than an unterminated last line) has a different field count
//    than the header;
//  - a required field is empty, not a number of its kind, out of range or not
//    finite (nan, inf); a non-empty optional field likewise (an empty optional
//    field means "unknown": NaN for rssi_dbm, fp_power_dbm and temp_c, -1 for
//    los, 0 for tag_id, none for sigma and vx,vy,vz);
//  - los other than 0, 1 or empty; an anchor kind other than uwb, ultrasonic
//    or empty (= uwb); a negative sigma; a groundtruth quaternion whose norm
//    differs from 1 by more than kQuaternionNormTolerance; vx,vy,vz partly empty;
//  - a repeated id in anchors.csv or tags.csv;
//  - time order: t_ns smaller than in the row before. imu.csv and
//    groundtruth.csv must strictly increase, so an equal t_ns whose row
//    differs from the previous one is an error too. range, tdoa and
//    ultrasonic rows may share a t_ns (several anchors per instant), but two
//    rows with the same t_ns and the same key (anchor, tag / anchor pair /
//    anchor) and different values are an error;
//  - a reference to an anchor not in anchors.csv or of the wrong kind
//    (range, tdoa: uwb; ultrasonic: ultrasonic), tdoa with anchor_a ==
//    anchor_b, a tag_id not in tags.csv (without tags.csv only tag 0 exists);
//  - meta.yaml: not valid YAML, not a mapping, a key with a value of the
//    wrong type or out of its domain (gravity, rate <= 0, a noise density < 0,
//    an unknown ranging kind).
// Warnings (ReadReport), row skipped (counted in skipped_rows):
//  - a row identical to an earlier row with the same t_ns (and key): a logger
//    that wrote a sample twice;
//  - the last line has no '\n' and fails any check above: cut by a crash.
// Warnings, data kept:
//  - the last line has no '\n' but passes every check (it may still have been
//    cut inside a number; hand-written files often lack the final newline);
//  - an optional file (tags, range, tdoa, ultrasonic, groundtruth) that is
//    empty: treated as absent (a writer that crashed before its first flush);
//  - unknown columns, blank lines, a UTF-8 byte order mark, a header cut by a
//    crash (file treated as empty), unknown meta.yaml keys.
//
// Files are read whole into memory and parsed with std::from_chars.
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "hal/recording/recording.h"
#include "hal/recording/recording_error.h"

namespace rilo {

/// Reads the recording in `dir`. Throws RecordingError (see the policy
/// above); warnings go to `report` if given (they are dropped otherwise).
Recording readRecording(const std::filesystem::path& dir, ReadReport* report = nullptr);

namespace recording {

// Per-file parsers on the file's whole text; `file` names it in messages.
// readRecording uses them; tests and tools may call them directly.
std::vector<Anchor> parseAnchors(std::string_view text, const std::string& file, ReadReport& report);
std::vector<Tag> parseTags(std::string_view text, const std::string& file, ReadReport& report);
/// `temp_c` gets one entry per sample if the file has a temp_c column, else stays empty.
void parseImu(std::string_view text, const std::string& file, std::vector<ImuSample>& imu,
              std::vector<double>& temp_c, ReadReport& report);
std::vector<RangeSample> parseRanges(std::string_view text, const std::string& file,
                                     const std::vector<Anchor>& anchors, const std::vector<Tag>& tags,
                                     ReadReport& report);
std::vector<TdoaSample> parseTdoa(std::string_view text, const std::string& file,
                                  const std::vector<Anchor>& anchors, ReadReport& report);
std::vector<UltrasonicSample> parseUltrasonic(std::string_view text, const std::string& file,
                                              const std::vector<Anchor>& anchors, ReadReport& report);
std::vector<GroundTruthPose> parseGroundTruth(std::string_view text, const std::string& file, ReadReport& report);

}  // namespace recording
}  // namespace rilo
