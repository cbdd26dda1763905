#pragma once
// Reader of sources.hardware: the DWM3000 and BMI263 sections map onto
// dw3000::Dw3000Config and bmi263::Bmi263Config (same field names; enums by
// their usual spellings), then the drivers' own validation runs and its
// message is reported at the offending key.
#include <vector>

#include "hal/recording/recording.h"
#include "rilod/config.h"
#include "rilod/config_reader.h"

namespace rilo::config_detail {

/// `anchors`: the surveyed anchors every responder must be one of (null: no
/// cross-check, when the hardware section is not the active source).
HardwareSourceConfig readHardware(const ConfigField& field, const std::vector<Anchor>* anchors);

}  // namespace rilo::config_detail
