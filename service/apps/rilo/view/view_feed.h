#pragma once
// The DDS side of `rilo view` and `rilo replay --view`: takes what the
// service publishes and feeds the page's state with it, until told to stop.
#include <functional>

#include "dds/subscriber.h"
#include "view_state.h"

namespace rilo::tool {

/// Odometry, pose, status and ranges from `subscriber` into `state` while
/// `keep_going()` (asked at least every 100 ms). Throws what the subscriber throws.
void feedView(dds::Subscriber& subscriber, ViewState& state, const std::function<bool()>& keep_going);

}  // namespace rilo::tool
