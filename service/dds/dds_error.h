#pragma once
// Cyclone DDS return codes turned into exceptions at set-up time: the message
// names the C call, the object it was about (topic, domain, ...) and the
// dds_strretcode() text. The publish path never throws; it returns WriteStatus
// (publisher.h).
#include <dds/dds.h>

#include <string_view>

namespace rilo::dds {

/// Throws std::runtime_error("<call>(<what>): <dds_strretcode> (<code>)").
[[noreturn]] void throwDdsError(std::string_view call, std::string_view what, dds_return_t code);

/// Returns `entity` if it is a valid handle (> 0), otherwise throws as above.
dds_entity_t checkEntity(dds_entity_t entity, std::string_view call, std::string_view what);

/// Throws as above unless `code` is DDS_RETCODE_OK.
void checkReturn(dds_return_t code, std::string_view call, std::string_view what);

}  // namespace rilo::dds
