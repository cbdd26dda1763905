#pragma once
// Values: the estimate of every variable, keyed. Variables are Pose3 (dim 6),
// Vec3 (dim 3; velocities and anchor positions) or ImuBias (dim 6); each has
// its own retraction. Tangent vectors are addressed through an ordering that
// assigns every key a column offset.
#include <stdexcept>
#include <unordered_map>
#include <variant>
#include <vector>

#include "estimation/graph/key.h"
#include "math/imu_bias.h"
#include "math/pose3.h"

namespace rilo {

using Variable = std::variant<Pose3, Vec3, ImuBias>;

/// Tangent dimension of a variable.
int variableDim(const Variable& v);
/// v (+) delta, delta pointing at variableDim(v) doubles.
Variable retractVariable(const Variable& v, const double* delta);
/// local(a, b): tangent vector taking a to b (same alternative required).
Eigen::VectorXd localVariable(const Variable& a, const Variable& b);

class Values {
 public:
  void insert(Key k, const Variable& v);  ///< throws std::invalid_argument if k exists
  void update(Key k, const Variable& v);  ///< throws std::out_of_range if k is missing
  void insertOrAssign(Key k, const Variable& v) { map_[k] = v; }
  void erase(Key k) { map_.erase(k); }
  bool exists(Key k) const { return map_.count(k) != 0; }
  std::size_t size() const { return map_.size(); }
  bool empty() const { return map_.empty(); }

  const Variable& at(Key k) const;
  template <class T>
  const T& at(Key k) const {
    const T* p = std::get_if<T>(&at(k));
    if (!p) throw std::invalid_argument("Values: variable " + keyString(k) + " has another type");
    return *p;
  }
  const Pose3& pose(Key k) const { return at<Pose3>(k); }
  const Vec3& vec3(Key k) const { return at<Vec3>(k); }
  const ImuBias& bias(Key k) const { return at<ImuBias>(k); }

  int dim(Key k) const { return variableDim(at(k)); }
  /// Keys sorted ascending (deterministic iteration).
  std::vector<Key> keys() const;

  /// Retracts key k in place by delta (variableDim doubles).
  void retractInPlace(Key k, const double* delta);

  auto begin() const { return map_.begin(); }
  auto end() const { return map_.end(); }

 private:
  std::unordered_map<Key, Variable> map_;
};

}  // namespace rilo
