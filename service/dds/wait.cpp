#include "dds/wait.h"

#include "dds/dds_error.h"
#include "dds/entity.h"

namespace rilo::dds {

bool waitForMatch(dds_entity_t participant, dds_entity_t endpoint, std::uint32_t status_mask,
                  const std::string& topic, std::chrono::nanoseconds timeout, const std::function<bool()>& done) {
  const std::string what = "topic '" + topic + "'";
  checkReturn(dds_set_status_mask(endpoint, status_mask), "dds_set_status_mask", what);
  const Entity waitset(checkEntity(dds_create_waitset(participant), "dds_create_waitset", what));
  checkReturn(dds_waitset_attach(waitset.get(), endpoint, endpoint), "dds_waitset_attach", what);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // Reading the matched status (inside done()) resets its trigger, so the
  // waitset wakes again only on the next change.
  while (!done()) {
    const auto remaining = deadline - std::chrono::steady_clock::now();
    if (remaining <= std::chrono::nanoseconds::zero()) return false;
    const dds_return_t rc = dds_waitset_wait(waitset.get(), nullptr, 0,
                                             std::chrono::duration_cast<std::chrono::nanoseconds>(remaining).count());
    if (rc < 0) throwDdsError("dds_waitset_wait", what, rc);
  }
  return true;
}

}  // namespace rilo::dds
