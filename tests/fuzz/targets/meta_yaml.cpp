// The recording's meta.yaml (hal/recording/meta_yaml.h).
#include <string_view>

#include "fuzz_targets.h"
#include "hal/recording/meta_yaml.h"
#include "hal/recording/recording_error.h"

namespace rilo::fuzz {

int metaYaml(const std::uint8_t* data, std::size_t size) {
  ReadReport report;
  try {
    (void)recording::parseMetaYaml(std::string_view(reinterpret_cast<const char*>(data), size), "meta.yaml", report);
  } catch (const RecordingError&) {
  }
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(metaYaml)
