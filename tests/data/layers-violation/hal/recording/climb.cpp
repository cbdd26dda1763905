// Fixture of the layer check: a relative path around the include folders.
#include "../../service/rilod/config.h"
