#include "estimation/smoother/smoother_method_names.h"

#include <stdexcept>

namespace rilo {

SmootherParams::Method smootherMethodFromName(const std::string& name) {
  for (const auto& [spelling, method] : kSmootherMethodNames) {
    if (name == spelling) return method;
  }
  std::string expected;
  for (std::size_t i = 0; i < kSmootherMethodNames.size(); ++i) {
    if (i > 0) expected += i + 1 == kSmootherMethodNames.size() ? " or " : ", ";
    expected += kSmootherMethodNames[i].first;
  }
  throw std::invalid_argument("unknown smoother '" + name + "' (expected " + expected + ")");
}

const char* smootherMethodName(SmootherParams::Method method) {
  for (const auto& [spelling, m] : kSmootherMethodNames) {
    if (m == method) return spelling.data();  // the table's literals are NUL-terminated
  }
  return "?";
}

}  // namespace rilo
