#pragma once
// A DDS domain participant. With an XML configuration the participant first
// creates the Cyclone domain instance with that configuration
// (dds_create_domain); participants of the same process and domain id share
// that instance, which lives until the last of them is destroyed. Without one,
// Cyclone's defaults apply (CYCLONEDDS_URI when set).
#include <cstdint>
#include <memory>
#include <string>

#include "dds/entity.h"

namespace rilo::dds {

namespace detail {
struct SharedDomain;  // an explicitly configured Cyclone domain instance (participant.cpp)
}

struct ParticipantOptions {
  std::uint32_t domain_id = 0;  ///< DDS domain (ROS_DOMAIN_ID); 0..232 with Cyclone's default port mapping
  std::string config_xml;       ///< Cyclone configuration (XML text or file:// URI); empty = defaults
};

/// Cyclone configuration that keeps all traffic on the loopback interface and
/// discovers peers by unicast to 127.0.0.1 (no multicast: `lo` has none, and
/// containers often have no other interface). For tests and single-host runs.
std::string loopbackConfigXml();

class Participant {
 public:
  /// Throws std::runtime_error naming the failing call and the domain.
  explicit Participant(const ParticipantOptions& options);
  ~Participant();
  Participant(const Participant&) = delete;
  Participant& operator=(const Participant&) = delete;

  dds_entity_t handle() const noexcept { return participant_.get(); }
  std::uint32_t domainId() const noexcept { return domain_id_; }

 private:
  std::uint32_t domain_id_;
  std::shared_ptr<detail::SharedDomain> domain_;  // declared before participant_: deleted after it
  Entity participant_;
};

}  // namespace rilo::dds
