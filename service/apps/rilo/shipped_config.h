#pragma once
// config/rilod.yaml as shipped, compiled into the rilo tool: `rilo replay`
// without --config runs its estimator, so the replay's defaults and the
// service's configuration are one estimator by construction (issue 36: the
// figures a user gets from either must be the same). The text is generated
// at configure time (service/apps/CMakeLists.txt); a change to the file
// re-runs CMake.
#include <string_view>

namespace rilo::tool {

/// The YAML text of config/rilod.yaml at build time.
std::string_view shippedConfigYaml();

/// The name messages give it.
inline constexpr std::string_view kShippedConfigName = "config/rilod.yaml (built in)";

}  // namespace rilo::tool
