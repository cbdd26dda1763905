// Fixture of the layer check: evaluation may include these (and <dds/...> in
// angle brackets is Cyclone DDS's, not ours).
#include <dds/dds.h>
#include "evaluation/report.h"
#include "hal/recording/recording.h"
#include "estimation/graph/factor.h"
