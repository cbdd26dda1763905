#pragma once
// The recorder's settings and the recording's description from the service
// configuration, so a recording made by rilod replays with the same
// parameters the service ran with.
#include "rilod/config.h"
#include "rilod/recorder.h"

namespace rilo {

/// flush interval and sync from `recording`, queue capacity from `realtime`.
RecorderOptions recorderOptions(const ServiceConfig& config);

/// meta.yaml (name, description, gravity, IMU noise model and rate, UWB lever
/// arm, ranging kind for hardware) and the surveyed anchors.
RecordingSetup recordingSetup(const ServiceConfig& config);

}  // namespace rilo
