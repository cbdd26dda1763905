// rilod's YAML configuration (service/rilod/config.h). Relative paths
// resolve against a folder that does not exist, so a file the text names
// is missing (a clear ConfigError) unless it is absolute.
#include <string_view>

#include "fuzz_targets.h"
#include "rilod/config.h"

namespace rilo::fuzz {

int rilodConfig(const std::uint8_t* data, std::size_t size) {
  try {
    (void)parseServiceConfig(std::string_view(reinterpret_cast<const char*>(data), size),
                             "/nonexistent-rilo-fuzz/rilod.yaml");
  } catch (const ConfigError&) {
  }
  return 0;
}

}  // namespace rilo::fuzz

RILO_FUZZ_ENTRY(rilodConfig)
