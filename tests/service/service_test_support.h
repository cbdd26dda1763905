#pragma once
// Helpers of the service tests: the source tree's location, temporary
// folders and files (shared support headers).
#include "support/source_tree.h"
#include "support/temp_dir.h"
