#pragma once
// meta.yaml of a recording <-> RecordingMeta. Keys (all optional, nested):
//   name, description, gravity, imu: {rate_hz, gyro_noise_density,
//   accel_noise_density, gyro_bias_random_walk, accel_bias_random_walk},
//   uwb: {lever_arm: [x, y, z]}, ultrasonic: {lever_arm: [x, y, z]},
//   ranging: ss-twr | ds-twr | tdoa.
// Reading: unknown keys are warnings; a value of the wrong type or out of its
// domain, a repeated key or invalid YAML is a RecordingError naming the key
// (dotted path, e.g. 'imu.rate_hz') and its line. Numbers are parsed with
// from_chars (so '.inf' and '.nan' are rejected); writing uses the shortest
// round-trip text.
#include <string>
#include <string_view>

#include "hal/recording/recording.h"
#include "hal/recording/recording_error.h"

namespace rilo::recording {

RecordingMeta parseMetaYaml(std::string_view text, const std::string& file, ReadReport& report);

/// YAML text for `meta`. Throws std::invalid_argument naming the field if a
/// value would be rejected by parseMetaYaml (non-finite, gravity <= 0, ...).
std::string formatMetaYaml(const RecordingMeta& meta);

}  // namespace rilo::recording
