#pragma once
// The one table of the smoothers' names, as rilod's configuration, rilo's
// flags and the reports spell them.
#include <array>
#include <string>
#include <string_view>
#include <utility>

#include "estimation/smoother/smoother_params.h"

namespace rilo {

inline constexpr std::array<std::pair<std::string_view, SmootherParams::Method>, 3> kSmootherMethodNames{{
    {"d-isam2", SmootherParams::Method::kDamped},
    {"isam2", SmootherParams::Method::kGaussNewton},
    {"dogleg", SmootherParams::Method::kDogleg},
}};

/// Parses a name of kSmootherMethodNames (throws std::invalid_argument otherwise).
SmootherParams::Method smootherMethodFromName(const std::string& name);
/// The name of `method` in kSmootherMethodNames ("?" for a value outside the enum).
const char* smootherMethodName(SmootherParams::Method method);

}  // namespace rilo
