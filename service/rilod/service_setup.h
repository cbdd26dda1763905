#pragma once
// From the configuration to the parts rilod assembles: the Service's options
// (everything but the callbacks, which are the daemon's: log, sd_notify,
// real-time set-up) and the replay source with its fault injection. main.cpp
// and the in-process tests build the service through these, so the tests run
// what the daemon runs.
#include <memory>

#include "hal/source.h"
#include "rilod/config.h"
#include "rilod/service.h"

namespace rilo {

/// ServiceOptions of `config`: anchors, estimator, DDS, queues, status
/// timeouts. The callbacks are left empty.
ServiceOptions serviceOptions(const ServiceConfig& config);

/// The Localizer parameters the service runs with: the estimator and imu
/// sections, and the ultrasonic beacons among the configured anchors.
/// `rilo replay --config` replays a recording with exactly these.
LocalizerParams localizerParams(const ServiceConfig& config);
/// The same from the estimator alone (no ultrasonic beacons: a replay takes
/// the recording's).
LocalizerParams localizerParams(const EstimatorConfig& estimator);

/// The replay source of sources.replay: pace, speed, time shift, and the
/// faults (a FaultInjectingSource around it) when any are configured.
/// Throws RecordingError for a malformed recording.
std::unique_ptr<SampleSource> makeReplaySource(const ReplaySourceConfig& replay);

}  // namespace rilo
