#include "dds/participant.h"

#include <map>
#include <mutex>
#include <stdexcept>
#include <string>

#include "dds/dds_error.h"

namespace rilo::dds {

// One explicitly configured Cyclone domain instance. Cyclone allows only one
// instance per domain id and process, and deleting it deletes every
// participant in it, so instances are shared and reference counted.
struct detail::SharedDomain {
  std::string config_xml;
  Entity domain;
};

namespace {

std::mutex g_domains_mutex;
std::map<std::uint32_t, std::weak_ptr<detail::SharedDomain>>& domainRegistry() {
  static std::map<std::uint32_t, std::weak_ptr<detail::SharedDomain>> registry;
  return registry;
}

// Cyclone's default port mapping (7400 + 250 * domain + ...) runs out of UDP
// ports above domain 232; its own error text is just "Error".
std::string domainLabel(std::uint32_t domain_id) {
  std::string label = "domain " + std::to_string(domain_id);
  if (domain_id > 232) label += ", above 232: UDP ports out of range with the default port mapping";
  return label;
}

}  // namespace

std::string loopbackConfigXml() {
  return "<CycloneDDS><Domain id=\"any\">"
         "<General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
         "<AllowMulticast>false</AllowMulticast></General>"
         "<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>"
         "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery>"
         "</Domain></CycloneDDS>";
}

Participant::Participant(const ParticipantOptions& options) : domain_id_(options.domain_id) {
  if (options.domain_id == DDS_DOMAIN_DEFAULT) {
    throw std::invalid_argument("Participant: domain_id must be an explicit domain, got DDS_DOMAIN_DEFAULT");
  }
  if (!options.config_xml.empty()) {
    const std::lock_guard<std::mutex> lock(g_domains_mutex);
    auto& registry = domainRegistry();
    std::shared_ptr<detail::SharedDomain> shared = registry[domain_id_].lock();
    if (shared) {
      if (shared->config_xml != options.config_xml) {
        throw std::invalid_argument("Participant: " + domainLabel(domain_id_) +
                                    " already exists in this process with a different config_xml");
      }
    } else {
      shared = std::make_shared<detail::SharedDomain>();
      shared->config_xml = options.config_xml;
      const dds_entity_t domain = dds_create_domain(domain_id_, options.config_xml.c_str());
      if (domain == DDS_RETCODE_PRECONDITION_NOT_MET) {
        throwDdsError("dds_create_domain", domainLabel(domain_id_) +
                                               " (already created without config_xml in this process)",
                      domain);
      }
      shared->domain = Entity(checkEntity(domain, "dds_create_domain", domainLabel(domain_id_)));
      registry[domain_id_] = shared;
    }
    domain_ = std::move(shared);
  }
  const dds_entity_t participant = dds_create_participant(domain_id_, nullptr, nullptr);
  participant_ = Entity(checkEntity(participant, "dds_create_participant", domainLabel(domain_id_)));
}

Participant::~Participant() {
  participant_.reset();
  if (domain_) {
    // Delete the domain instance with its last user, under the registry lock
    // so a concurrent constructor cannot pick up a dying instance.
    const std::lock_guard<std::mutex> lock(g_domains_mutex);
    domain_.reset();
  }
}

}  // namespace rilo::dds
