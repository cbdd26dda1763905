#pragma once
// Fixture of the layer check (tests/CMakeLists.txt): the estimation library
// reaching up, and the start-up room reaching the tracking room above it. A
// range in brackets, [0, 1), must not hide the includes after it.
#include <vector>
#include "rilod/config.h"
#include "estimation/graph/factor.h"
#include <evaluation/tum.h>
#include "estimation/tracking/localizer.h"
#include "estimation/assembly/range_imu_graph.h"
