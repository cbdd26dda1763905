#pragma once
// Blocking until an endpoint's matched status satisfies a condition, on a
// DDS waitset (no polling). Set-up helper: throws on DDS errors.
#include <dds/dds.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace rilo::dds {

/// Waits until `done()` is true, re-checking whenever a status in
/// `status_mask` of `endpoint` (a reader or writer of `participant`) changes.
/// Returns false if `timeout` passes first.
bool waitForMatch(dds_entity_t participant, dds_entity_t endpoint, std::uint32_t status_mask,
                  const std::string& topic, std::chrono::nanoseconds timeout, const std::function<bool()>& done);

}  // namespace rilo::dds
