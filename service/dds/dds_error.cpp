#include "dds/dds_error.h"

#include <stdexcept>
#include <string>

namespace rilo::dds {

void throwDdsError(std::string_view call, std::string_view what, dds_return_t code) {
  std::string message(call);
  message += "(";
  message += what;
  message += "): ";
  message += dds_strretcode(code);
  message += " (";
  message += std::to_string(code);
  message += ")";
  throw std::runtime_error(message);
}

dds_entity_t checkEntity(dds_entity_t entity, std::string_view call, std::string_view what) {
  if (entity <= 0) throwDdsError(call, what, entity == 0 ? DDS_RETCODE_ERROR : entity);
  return entity;
}

void checkReturn(dds_return_t code, std::string_view call, std::string_view what) {
  if (code != DDS_RETCODE_OK) throwDdsError(call, what, code);
}

}  // namespace rilo::dds
