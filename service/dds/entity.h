#pragma once
// Owning handle of one Cyclone DDS entity (domain, participant, topic, reader,
// writer, waitset, condition): dds_delete() on destruction, move-only.
// Deleting an entity deletes its children, so an Entity must not outlive the
// entity it was created in (members are declared parent first).
#include <dds/dds.h>

#include <utility>

namespace rilo::dds {

class Entity {
 public:
  Entity() = default;
  explicit Entity(dds_entity_t handle) noexcept : handle_(handle) {}
  ~Entity() { reset(); }
  Entity(Entity&& other) noexcept : handle_(std::exchange(other.handle_, 0)) {}
  Entity& operator=(Entity&& other) noexcept {
    if (this != &other) {
      reset();
      handle_ = std::exchange(other.handle_, 0);
    }
    return *this;
  }
  Entity(const Entity&) = delete;
  Entity& operator=(const Entity&) = delete;

  dds_entity_t get() const noexcept { return handle_; }
  explicit operator bool() const noexcept { return handle_ > 0; }

  /// Deletes the entity (and its children). Errors are ignored: the entity may
  /// already be gone with its parent.
  void reset() noexcept {
    if (handle_ > 0) static_cast<void>(dds_delete(handle_));
    handle_ = 0;
  }

 private:
  dds_entity_t handle_ = 0;
};

}  // namespace rilo::dds
