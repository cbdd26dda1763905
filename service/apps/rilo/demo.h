#pragma once
// `rilo demo`: simulate a ranging + IMU session and solve it in batch with each
// range noise model, printing the accuracy. The first runnable showcase of the
// estimation core; it becomes the service demo once rilod lands.
#include <cstdint>
#include <string>
#include <vector>

namespace rilo::tool {

struct DemoOptions {
  std::uint64_t seed = 1;
  double seconds = 60.0;
  double range_hz = 40.0;
  double nlos_fraction = 0.25;
  std::vector<std::string> noise_models{"gaussian", "huber", "cauchy", "asymmetric"};
};

/// Returns the process exit code.
int runDemo(const DemoOptions& options);

}  // namespace rilo::tool
