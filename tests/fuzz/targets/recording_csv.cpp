// The recording's CSV files (hal/recording/recording_reader.h): the first
// byte picks the file kind, the rest is its text.
#include <string>
#include <string_view>
#include <vector>

#include "fuzz_targets.h"
#include "hal/recording/recording_error.h"
#include "hal/recording/recording_reader.h"

namespace rilo::fuzz {

int recordingCsv(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  ReadReport report;
  // Eight anchors and one tag, as a recording's anchors.csv and tags.csv give them.
  std::vector<Anchor> anchors(8);
  for (std::uint32_t i = 0; i < anchors.size(); ++i) anchors[i].id = i;
  std::vector<Tag> tags(1);
  try {
    switch (data[0] % 8) {
      case 0: (void)recording::parseAnchors(text, "anchors.csv", report); break;
      case 1: (void)recording::parseTags(text, "tags.csv", report); break;
      case 2: {
        std::vector<ImuSample> imu;
        std::vector<double> temp_c;
        recording::parseImu(text, "imu.csv", imu, temp_c, report);
        break;
      }
      case 3: (void)recording::parseRanges(text, "range.csv", anchors, tags, report); break;
      case 4: (void)recording::parseTdoa(text, "tdoa.csv", anchors, report); break;
      case 5: (void)recording::parseUltrasonic(text, "ultrasonic.csv", anchors, report); break;
      default: (void)recording::parseGroundTruth(text, "groundtruth.csv", report); break;
    }
  } catch (const RecordingError&) {
    // A clear refusal naming the file and line: what a malformed file must get.
  }
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(recordingCsv)
